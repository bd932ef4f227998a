#pragma once
// The `multiparticles` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/frame_option.h"
#include "pm/cli/material_options.h"
#include "pm/cli/run_tool.h"
#include "pm/field/sizing.h"
#include "pm/sample/multiparticles.h"
#include "pm/volume/mcinit.h"

namespace pm {

struct MultiParticlesRun {
  pm::MaterialOptions materials;
  std::string seeds_path;
  std::string labels_path;
  std::string sizing_path;
  std::string output;
  std::string energy = "cotangent";
  pm::MultiParticleParams params;
  int decimate = 1;
  bool no_surfaces = false;
  bool no_repair = false;
  CLI::Option* spacing = nullptr;
  pm::WorldFrame frame = pm::WorldFrame::lps;
};

void add_multiparticles_options(CLI::App& app, MultiParticlesRun& r);
void run_multiparticles(MultiParticlesRun& r, const CommonFlags& flags);

}  // namespace pm
