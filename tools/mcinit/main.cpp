// mcinit: particle seeds from marching-cubes vertices of the reconstructed
// isosurface, or on every material boundary of a label map (SPEC §5,
// dissertation §5.3.3 and Chapter 6).
// (pm/cli/mcinit_run.h)
#include "pm/cli/mcinit_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool("mcinit",
                "Seed particles with marching-cubes vertices: one seed per grid edge crossing F = iso of the "
                "reconstructed field, projected onto it with Newton steps along grad F, normals = grad F / |grad F|, "
                "so every surface component is seeded. With --junctions (label maps): seeds at the midpoints of "
                "edges between two labels and at the centres of cells holding 3 or 4+ labels (PLY scalars "
                "junction, label_a..label_d).",
                "mcinit skull_2.9.inr seeds.ply --iso 2.9 --kernel mix --decimate 2");
  pm::McInitRun r;
  pm::add_mcinit_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_mcinit(r, tool.flags); });
}
