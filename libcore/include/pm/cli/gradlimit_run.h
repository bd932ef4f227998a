#pragma once
// The `gradlimit` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/run_tool.h"
#include "pm/volume/gradlimit.h"

namespace pm {

struct GradLimitRun {
  std::string input;
  std::string output;
  std::string method = "propagate";
  std::string far_field = "flat";
  pm::GradLimitParams params;
  std::string inward;
  double band = 0;
  double max_size = 0;
  CLI::Option* max_size_opt = nullptr;
  bool gzip = false;
};

void add_gradlimit_options(CLI::App& app, GradLimitRun& r);
void run_gradlimit(GradLimitRun& r, const CommonFlags& flags);

}  // namespace pm
