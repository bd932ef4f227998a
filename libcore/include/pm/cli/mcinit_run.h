#pragma once
// The `mcinit` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/field_options.h"
#include "pm/cli/frame_option.h"
#include "pm/cli/run_tool.h"
#include "pm/volume/mcinit.h"

namespace pm {

struct McInitRun {
  std::string input;
  std::string output;
  std::string kernel = "bspline";
  pm::McInitParams params;
  bool junctions = false;
  CLI::Option* iso = nullptr;
  pm::WorldFrame frame = pm::WorldFrame::lps;
};

void add_mcinit_options(CLI::App& app, McInitRun& r);
void run_mcinit(McInitRun& r, const CommonFlags& flags);

}  // namespace pm
