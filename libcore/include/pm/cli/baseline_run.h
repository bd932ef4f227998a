#pragma once
// The `baseline` run (issue #5, #19): marching cubes, CGAL Mesh_3 on an
// isosurface or a label map, optionally with the volume and CGAL's sliver
// optimisers, the facet size searched for a vertex count; results and the
// size search go into pm::stats().
#include <CLI/CLI.hpp>
#include <cstddef>
#include <string>

#include "pm/baseline/baseline.h"
#include "pm/cli/field_options.h"
#include "pm/io/frame.h"

namespace pm {

struct BaselineRun {
  std::string mode;              ///< mc | cgal | cgal-labels
  FieldOptions field;            ///< -i VOLUME --iso C (cgal-labels: a label map)
  std::string inside = "auto";   ///< below | above | auto
  std::string outside = "auto";  ///< cgal-labels: the label not meshed, or auto
  std::string output, tets;
  std::size_t vertices = 0;  ///< search the facet size for about this many vertices (0: --size)
  double size = 0, tolerance = 0.1;
  int max_runs = 5;
  bool no_optimise = false;
  CgalMeshParams params;
  WorldFrame frame = WorldFrame::lps;
};

void add_baseline_options(CLI::App& app, BaselineRun& r);
/// \throw UsageError for inconsistent options (before any work); the
/// errors of the meshers otherwise.
void run_baseline(BaselineRun& r, int threads, std::uint64_t seed);

}  // namespace pm
