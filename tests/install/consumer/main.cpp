// Ten lines against the installed libcore: a volume in world units.
#include <cstdio>

#include "pm/base/volume.h"

int main() {
  pm::Volume v(pm::VoxelType::f32, pm::Dims{3, 4, 5}, pm::Geometry::with_spacing(0.5, 0.5, 2.0));
  for (std::size_t i = 0; i < v.count(); ++i) v.set(i, double(i));
  const pm::ValueRange r = pm::value_range(v);
  const pm::Box b = v.world_bounds();
  std::printf("consumer: %zu voxels, values %g to %g, world box x %g y %g z %g\n", v.count(), r.lo, r.hi, b.hi.x,
              b.hi.y, b.hi.z);
  return v.count() == 60 && r.hi == 59 && b.hi.x == 1.0 && b.hi.y == 1.5 && b.hi.z == 8.0 ? 0 : 1;
}
