#pragma once
// The `morph` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/run_tool.h"
#include "pm/volume/labels.h"
#include "pm/volume/morphology.h"

namespace pm {

struct MorphRun {
  std::string input;
  std::string output;
  std::string op;
  std::string stencil = "ball";
  std::string ops;
  std::string labels;
  pm::LabelMorphParams params;
  int iterations = 1;
  bool grey = false;
  bool no_gzip = false;  ///< --no-gzip: write the output uncompressed
};

void add_morph_options(CLI::App& app, MorphRun& r);
void run_morph(MorphRun& r, const CommonFlags& flags);

}  // namespace pm
