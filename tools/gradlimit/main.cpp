// gradlimit: Persson's gradient limiting of a sizing field (SPEC §5,
// dissertation §5.3.2).
// (pm/cli/gradlimit_run.h)
#include "pm/cli/gradlimit_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool("gradlimit",
                "Limit the gradient of a sizing field h (world units; spacing from the header): output the "
                "largest h' <= h with |grad h'| <= delta. Voxels with h <= 0 (or NaN/Inf with --nan-unknown) are "
                "unknown and receive the extension min_y h(y) + delta |x - y|, so the output is > 0 everywhere.",
                "gradlimit sizing.nrrd sizing_limited.nrrd --delta 0.3\n"
                "  gradlimit h.nrrd h_volume.nrrd --inward surface.ply --delta 0.2 --max-size 8   (interior sizing "
                "for volume packing)");
  pm::GradLimitRun r;
  pm::add_gradlimit_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_gradlimit(r, tool.flags); });
}
