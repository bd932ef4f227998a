#pragma once
// The `tetlabel` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/conform_tets.h"
#include "pm/cli/field_options.h"
#include "pm/cli/frame_option.h"
#include "pm/cli/material_options.h"
#include "pm/cli/run_tool.h"
#include "pm/io/tet_mesh.h"
#include "pm/mesh/meshstats_materials.h"
#include "pm/mesh/pipeline.h"
#include "pm/mesh/surface_improve.h"
#include "pm/mesh/tetlabel.h"
#include "pm/mesh/tetlabel_materials.h"

namespace pm {

struct TetLabelRun {
  std::string points;
  std::string output;
  std::string tets;
  std::string inside = "auto";
  std::string outside = "auto";
  std::string surfaces;
  std::vector<std::string> tets_list;
  pm::MaterialOptions materials;
  bool repair = true;
  int improve = 0;
  pm::FieldOptions fo;
  pm::ConformRun cr;
  pm::WorldFrame frame = pm::WorldFrame::lps;
};

void add_tetlabel_options(CLI::App& app, TetLabelRun& r);
void run_tetlabel(TetLabelRun& r, const CommonFlags& flags, const CLI::App& app);

}  // namespace pm
