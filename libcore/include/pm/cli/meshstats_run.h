#pragma once
// The `meshstats` run: its options and the work behind them (the tool's main
// only parses and calls; issue #16).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <string>

#include "pm/cli/field_options.h"
#include "pm/cli/run_tool.h"
#include "pm/io/poly_mesh.h"
#include "pm/io/tet_mesh.h"
#include "pm/mesh/coverage.h"
#include "pm/mesh/meshstats.h"
#include "pm/mesh/meshstats_materials.h"
#include "pm/mesh/quad_mesh.h"
#include "pm/mesh/tet_quality.h"

namespace pm {

struct MeshStatsRun {
  std::string mesh_path;
  std::string output;
  std::string sizing_path;
  std::string require;
  bool no_self = false;
  bool single = false;
  std::string seeds_path;
  std::size_t min_seeds = 8;
  pm::FieldOptions fo;
};

void add_meshstats_options(CLI::App& app, MeshStatsRun& r);
void run_meshstats(MeshStatsRun& r, const CommonFlags& flags);

}  // namespace pm
