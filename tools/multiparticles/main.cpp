// multiparticles: hierarchical particle sampling of the junctions of a
// multi-material volume (SPEC §6, Meyer 2008 Chapter 6): quadruple points,
// triple curves, then the interfaces between each pair of materials.
// (pm/cli/multiparticles_run.h)
#include "pm/cli/multiparticles_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool(
      "multiparticles",
      "Sample every junction of a multi-material volume with particles (world units throughout): one particle "
      "on each quadruple point (0-cell), chains along each triple curve (1-cells), then near-hexagonal "
      "packings on each interface between two materials (2-cells); each level relaxes while the lower ones stay "
      "fixed and repel it. Junctions are found from seeds: `mcinit --junctions` points (--seeds), a label map "
      "(--labels), or by default the argmax labels of the materials on a grid at their resolution. Output: a PLY "
      "point set with x y z, nx ny nz (surfaces: unit normal from label_a into label_b; zero on curves and "
      "points) and vertex scalars junction (number of materials meeting: 4 point, 3 curve, 2 surface), label_a < "
      "label_b < label_c < label_d (-1 unused), spacing (local h, world units), energy, residual (max |f_a - f_b| "
      "at the particle, world units).",
      "multiparticles --materials labels.nrrd --spacing 2 -o points.ply --stats -");
  pm::MultiParticlesRun r;
  pm::add_multiparticles_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_multiparticles(r, tool.flags); });
}
