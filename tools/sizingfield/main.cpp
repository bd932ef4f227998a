// sizingfield: initial sizing field h0 = 2ε min(LFS, 1/|κmax|) / g near the
// surface (§5.3.2), from signed distance volumes and their medial axes.
// (pm/cli/sizingfield_run.h)
#include "pm/cli/run_tool.h"
#include "pm/cli/sizingfield_run.h"

int main(int argc, char** argv) {
  pm::Tool tool("sizingfield",
                "Initial sizing field (target edge length, world units) near a surface: h = 2 eps min(LFS, "
                "1/|kmax|) / g, LFS = distance to the nearest medial-axis point, kmax the larger principal "
                "curvature, both at each node's closest surface point; at least --hmin. Nodes farther than "
                "--band voxels from the surface are 0 (unknown: gradlimit extends them). Several --sdf/--ma "
                "pairs (one per material) give the minimum.",
                "sizingfield --sdf brain_sdf.nrrd --ma brain_ma.ply -o brain_h.nrrd --eps 0.5");
  pm::SizingFieldRun r;
  pm::add_sizingfield_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_sizingfield(r, tool.flags); });
}
