// morph: binary morphology of masks and label maps, per material, with
// downsampling and voting fill (SPEC §2, dissertation §2.5.1 and §6.6.1).
// (pm/cli/morph_run.h)
#include "pm/cli/morph_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool("morph",
                "Binary morphology (voxel units) of a mask or label map: each processed label's mask is "
                "eroded/dilated/opened/closed separately and recombined (a voxel claimed by several labels keeps "
                "its own label if it is one of them, else takes the smallest; voxels left unclaimed are empty). "
                "Then optional downsampling (block majority) and voting fill of empty voxels (most common of the "
                "6 face neighbours, ties to the smallest label). Outside the volume counts as background. "
                "Stencils: plus (7 voxels), ball (19), cube (27), f1..f4 = Table 2.1's feature sizes 1-4.",
                "morph torso.nrrd clean.nrrd --labels 0-4 --ops \"close:f4,open:f2; 3=open:f2,close:f1\" "
                "--downsample 2 --vote");
  pm::MorphRun r;
  pm::add_morph_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_morph(r, tool.flags); });
}
