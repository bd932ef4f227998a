// A consumer of the installed libcore: a volume in world units, to a NRRD file and back.
#include <cstdio>
#include <string>

#include "pm/io/volume_io.h"

int main(int argc, char** argv) {
  pm::Volume v(pm::VoxelType::f32, pm::Dims{3, 4, 5}, pm::Geometry::with_spacing(0.5, 0.5, 2.0));
  for (std::size_t i = 0; i < v.count(); ++i) v.set(i, double(i));
  const std::string path = std::string(argc > 1 ? argv[1] : ".") + "/consumer.nrrd";
  pm::write_volume(v, path);
  const pm::Volume r = pm::read_volume(path);
  const pm::Box b = r.world_bounds();
  std::printf("consumer: %zu voxels, last %g, world box to (%g, %g, %g)\n", r.count(), r.get(59), b.hi.x, b.hi.y,
              b.hi.z);
  return r.count() == 60 && r.get(59) == 59 && b.hi.x == 1.0 && b.hi.y == 1.5 && b.hi.z == 8.0 ? 0 : 1;
}
