#pragma once
// The `volconv` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/run_tool.h"
#include "pm/field/materials.h"
#include "pm/field/mesh_sdf.h"
#include "pm/field/volume_field.h"
#include "pm/volume/labels.h"

namespace pm {

struct VolConvRun {
  std::string input;
  std::string output;
  std::string labels;
  std::string merge;
  std::string type;
  std::string inside = "auto";
  double distance_iso = 0;
  bool info = false;
  bool sdf = false;
  bool allow_nonfinite = false;
  pm::MeshSdfParams sp;
  CLI::Option* thr = nullptr;
  CLI::Option* dist = nullptr;
  bool argmax = false;
  std::string pad = "0";        ///< N, auto or auto:N (see --pad)
  std::string pad_value = "0";  ///< number, new or auto
  std::size_t min_voxels = 0;
  bool no_gzip = false;  ///< --no-gzip: write the output uncompressed
};

void add_volconv_options(CLI::App& app, VolConvRun& r);
void run_volconv(VolConvRun& r, const CommonFlags& flags, const CLI::App& app);

}  // namespace pm
