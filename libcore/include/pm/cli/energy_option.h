#pragma once
// --energy, --step-control and --step-factor, shared by the particle tools.
#include <CLI/CLI.hpp>
#include <string>

#include "pm/sample/engine.h"

namespace pm {

/// Adds --energy NAME (cotangent | radial, checked by CLI11) writing the name into `name`.
void add_energy_option(CLI::App& app, std::string& name);
/// The energy of a --energy name. \throw UsageError for another name.
ParticleEnergy energy_named(const std::string& name);

/// Adds --step-control (quadratic | factor) and --step-factor (> 1); `note`
/// ends the help with the tool's own default and why. Returns the
/// --step-control option (to tell whether it was given).
CLI::Option* add_step_options(CLI::App& app, StepControl& control, double& factor, const std::string& note);
/// "quadratic" or "factor", for --stats.
const char* step_control_name(StepControl c);

}  // namespace pm
