// medialaxis: medial-axis points of the zero set of a signed distance volume
// by the foot-point method (§5.3.1).
// (pm/cli/medialaxis_run.h)
#include "pm/cli/medialaxis_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool("medialaxis",
                "Find medial-axis points of the surface d = 0 of a signed distance volume (float, negative "
                "inside, world units) by the foot-point method: where the characteristic from the closest "
                "surface point turns by more than alpha within a voxel. Writes a PLY point set with vertex "
                "property 'distance' (to the surface, world units); inner and outer medial axis by default.",
                "medialaxis brain_sdf.nrrd brain_ma.ply --volume brain_ma.nrrd");
  pm::MedialAxisRun r;
  pm::add_medialaxis_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_medialaxis(r, tool.flags); });
}
