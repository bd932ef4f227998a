#pragma once
// The `particles` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/field_options.h"
#include "pm/cli/frame_option.h"
#include "pm/cli/reference_particles.h"
#include "pm/cli/run_tool.h"
#include "pm/cli/volume_particles.h"
#include "pm/field/implicits.h"
#include "pm/field/sizing.h"
#include "pm/field/volume_field.h"
#include "pm/sample/particles.h"

namespace pm {

struct ParticlesRun {
  std::string implicit;
  std::string input;
  std::string hp_field;
  std::string sizing_path;
  std::string seeds_path;
  std::string output;
  std::string kernel = "bspline";
  std::string energy = "cotangent";
  pm::ParticleParams params;
  bool coarse = false;
  std::string scenario;
  CLI::Option* iso_opt = nullptr;
  CLI::Option* spacing = nullptr;
  CLI::Option* density = nullptr;
  CLI::Option* lattice = nullptr;
  CLI::Option* tol_opt = nullptr;
  CLI::Option* coarse_tol_opt = nullptr;
  CLI::Option* coarse_pop_opt = nullptr;
  CLI::Option* step_control_opt = nullptr;
  CLI::Option* iters_opt = nullptr;
  CLI::Option* ctf = nullptr;
  bool volume = false;
  pm::VolumeRun vr;
  pm::MaterialOptions materials;
  pm::WorldFrame frame = pm::WorldFrame::lps;
};

void add_particles_options(CLI::App& app, ParticlesRun& r);
void run_particles(ParticlesRun& r, const CommonFlags& flags);

}  // namespace pm
