// quadmesh: a quad-dominant surface mesh from a triangulated two-type
// particle packing (particles --quads, Chapter 7; pm/cli/quad_run.h).
#include "pm/cli/frame_option.h"
#include "pm/cli/quad_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool("quadmesh",
                "Pair the triangles of a surface whose vertices are two-type particles (particles --quads) into "
                "quads: the edges between like particles are the diagonals of the checkerboard's squares and are "
                "dropped; leftover triangles are paired across other edges where the quad is good enough (corner "
                "angles within --max-corner-deviation of 90 degrees, folds under --max-fold), then by short "
                "augmenting paths, else kept. With the surface's field (-i VOLUME --iso C or --implicit SPEC) the "
                "quads are smoothed on it (--smooth passes; every vertex stays on F = iso). --gmsh recombines the "
                "same triangles with Gmsh's Blossom matching instead (the baseline). The result keeps the "
                "vertices' count, is water-tight when the input is, and is written with its quads (.ply .obj "
                ".off); --stats has the quad share, corner angles, valence and scaled Jacobian. World units.",
                "particles -i sdf.nrrd --iso 0 --spacing 1.5 --quads -o typed.ply\n"
                "  tetlabel typed.ply -i sdf.nrrd --iso 0 --improve 0 -o tri.ply\n"
                "  quadmesh tri.ply --types typed.ply -i sdf.nrrd --iso 0 -o quads.ply --stats quads.json\n"
                "  quadmesh tri.ply --gmsh -i sdf.nrrd --iso 0 -o gmsh.ply   # the baseline");
  pm::QuadRun r;
  pm::add_quad_options(tool.app, r);
  pm::add_frame_option(tool.app, r.frame);
  return tool.run(argc, argv, [&] { pm::run_quads(r); });
}
