// particles: sample an implicit surface or a volume's isosurface with the
// dynamic particle system of SPEC §3 (Meyer 2008, Chapter 3).
// (pm/cli/particles_run.h)
#include "pm/cli/particles_run.h"
#include "pm/cli/run_tool.h"

int main(int argc, char** argv) {
  pm::Tool tool("particles",
                "Distribute particles on an isosurface F = iso (world units throughout): they repel each other "
                "with a compact energy and settle in a near-hexagonal packing with spacing s, finer where the "
                "surface is curved (--density) or following a sizing field (--sizing). Output: a PLY point set "
                "with x y z, nx ny nz (outward normals) and vertex scalars energy, spacing (local spacing, world "
                "units) and curvature (curvedness sqrt(k1^2 + k2^2), 1/world units).",
                "particles -i brain.nrrd --iso 0.5 --spacing 2 --density 5 -o brain.ply --stats -\n"
                "  particles -i chan3D.xml --field chan3D.fld:u --iso 0.5 --spacing 0.05 -o u.ply\n"
                "  particles --scenario teardrop --spacing 0.0385 -o teardrop.ply\n"
                "  particles --volume -i sdf.nrrd --iso 0 --fixed surface.ply --sizing h_volume.nrrd -o interior.ply");
  pm::ParticlesRun r;
  pm::add_particles_options(tool.app, r);
  return tool.run(argc, argv, [&] { pm::run_particles(r, tool.flags); });
}
