#pragma once
// The `sizingfield` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/run_tool.h"
#include "pm/volume/medialaxis.h"
#include "pm/volume/sizingfield.h"

namespace pm {

struct SizingFieldRun {
  std::vector<std::string> sdfs;
  std::vector<std::string> mas;
  std::string output;
  std::string lfs_out;
  pm::SizingFieldParams params;
  bool no_contract = false;
  bool at_node = false;
  bool gzip = false;  ///< --gzip: compress the outputs
};

void add_sizingfield_options(CLI::App& app, SizingFieldRun& r);
void run_sizingfield(SizingFieldRun& r, const CommonFlags& flags);

}  // namespace pm
