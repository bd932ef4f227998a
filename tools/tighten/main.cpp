// tighten: smooth a binary mask into a signed distance volume whose zero set
// has radius of curvature >= r (Williams–Rossignac tightening, §2.5.2).
// (pm/cli/tighten_run.h)
#include "pm/cli/run_tool.h"
#include "pm/cli/tighten_run.h"

int main(int argc, char** argv) {
  pm::Tool tool("tighten",
                "Tighten a binary mask (two distinct values, the larger inside) with radius R: curvature flow "
                "of its signed distance, kept between the opening (round) and the closing (fillet) with a ball "
                "of radius R. Output: float signed distance to the tightened surface, world units, negative "
                "inside (--positive-inside for Chapter 6 indicator functions). A mask closer than R + 3 voxels "
                "to the border is padded (the output grid grows; its origin moves).",
                "tighten brain.nrrd brain_sdf.nrrd --radius 1.5 --upsample 2\n"
                "  tighten ct_mask.nrrd ct_sdf.nrrd          # radius auto: the largest voxel spacing\n"
                "  tighten labels.nrrd 'out/sdf_%d.nrrd' --per-label --radius 1 --upsample 2   # Chapter 6");
  pm::TightenRun r;
  pm::add_tighten_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_tighten(r, tool.flags); });
}
