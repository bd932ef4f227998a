// volconv: convert volumes between formats, report headers, make signed
// distance volumes of closed meshes, and do label-map chores.
// (pm/cli/volconv_run.h)
#include "pm/cli/run_tool.h"
#include "pm/cli/volconv_run.h"

int main(int argc, char** argv) {
  pm::Tool tool("volconv",
                "Convert volumes between NRRD (.nrrd/.nhdr), VDB (.vdb), MetaImage (.mha/.mhd), NIfTI "
                "(.nii/.nii.gz) and INR (.inr/.inr.gz) by extension, keeping geometry (origin, spacing, "
                "directions; world units) and anatomy: every file is read into the LPS world frame (NIfTI's RAS "
                "and the NRRD spaces converted) and written out of it. Also: --info prints the header as JSON; --sdf "
                "turns a closed mesh "
                "(.off/.obj/.ply/.stl) into a signed distance volume (negative inside, world units); --labels "
                "and --merge make masks and relabel label maps.",
                "volconv brain.nii.gz brain.nrrd && volconv bunny.off bunny.nrrd --sdf --voxel 0.002");
  pm::VolConvRun r;
  pm::add_volconv_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_volconv(r, tool.flags, tool.app); });
}
