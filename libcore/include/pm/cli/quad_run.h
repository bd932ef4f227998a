#pragma once
// The `quadmesh` run (issue #20): read a triangle surface whose vertices are
// two-type particles (`particles --quads`, meshed by `tetlabel`), take each
// vertex's type, pair triangles into quads (pm::quad_dominant), write the
// quad-dominant mesh and its quality (pm::quad_quality) into pm::stats().
// With `gmsh`, Gmsh recombines the same triangles instead (the baseline).
#include <CLI/CLI.hpp>
#include <string>

#include "pm/baseline/gmsh_recombine.h"
#include "pm/cli/field_options.h"
#include "pm/mesh/quad_smooth.h"
#include "pm/io/frame.h"
#include "pm/mesh/quad_mesh.h"

namespace pm {

struct QuadRun {
  std::string surface;  ///< triangle mesh (any read_mesh format)
  /// Typed particles (`particles --quads` output, vertex property `type`),
  /// when the surface itself has no `type`: a surface vertex takes the type
  /// of the particle at the same position ("" = the surface's own `type`).
  std::string types;
  std::string output;   ///< .ply .obj .off (quads kept)
  QuadParams params;
  /// The baseline instead: Gmsh's recombination of the same triangles
  /// (pm::gmsh_recombine); no types needed.
  bool gmsh = false;
  GmshRecombineParams gmsh_params;
  /// The surface's field (-i VOLUME --iso C, or --implicit): when given, the
  /// quads are smoothed on it (pm::smooth_quads, `smooth.passes`).
  FieldOptions field;
  QuadSmoothParams smooth;
  WorldFrame frame = WorldFrame::lps;
  bool ascii = false;
};

void add_quad_options(CLI::App& app, QuadRun& r);
/// \throw UsageError for an output extension that keeps no quads, before any work.
void check_quad_options(const QuadRun& r);
void run_quads(const QuadRun& r);

}  // namespace pm
