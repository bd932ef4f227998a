#pragma once
// --energy, shared by the particle tools: the pair energy by name.
#include <CLI/CLI.hpp>
#include <string>

#include "pm/sample/engine.h"

namespace pm {

/// Adds --energy NAME (cotangent | radial, checked by CLI11) writing the name into `name`.
void add_energy_option(CLI::App& app, std::string& name);
/// The energy of a --energy name. \throw UsageError for another name.
ParticleEnergy energy_named(const std::string& name);

}  // namespace pm
