#pragma once
// The `tighten` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/run_tool.h"
#include "pm/volume/tighten.h"

namespace pm {

struct TightenRun {
  std::string input;
  std::string output;
  pm::TightenParams params;
  bool per_label = false;
  std::string radius = "auto";
  std::string upsample = "auto";
  std::string outside_band = "0";
  bool gzip = false;
};

void add_tighten_options(CLI::App& app, TightenRun& r);
void run_tighten(TightenRun& r, const CommonFlags& flags);

}  // namespace pm
