#pragma once
// The `medialaxis` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/frame_option.h"
#include "pm/cli/run_tool.h"
#include "pm/volume/medialaxis.h"

namespace pm {

struct MedialAxisRun {
  std::string input;
  std::string output;
  std::string volume;
  std::string side = "both";
  std::string inside = "below";
  std::string sdf_out;
  bool lfs_only = false;
  double iso = std::nan("");
  pm::MedialAxisParams params;
  pm::WorldFrame frame = pm::WorldFrame::lps;
};

void add_medialaxis_options(CLI::App& app, MedialAxisRun& r);
void run_medialaxis(MedialAxisRun& r, const CommonFlags& flags);

}  // namespace pm
