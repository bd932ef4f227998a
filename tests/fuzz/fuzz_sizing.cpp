// The sizing-field input of `particles --sizing FILE` and `meshstats --sizing
// FILE`: a volume read with pm::read_volume and wrapped in pm::SizingField,
// which refuses non-finite or non-positive h; accepted fields are sampled at
// their corners, centre and just outside their box.
#include <cstdio>
#include <cstdlib>

#include "fuzz_util.h"
#include "pm/field/sizing.h"
#include "pm/io/volume_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = pm::fuzz::put_file("sizing.nrrd", data, size);
  pm::fuzz::expect_pm_errors_only([&] {
    const pm::SizingField h(pm::read_volume(path), path);
    const pm::Box& b = h.bounds();
    const pm::Vec3 pts[] = {b.lo, b.hi, (b.lo + b.hi) * 0.5, b.hi + (b.hi - b.lo) * 0.01 + pm::Vec3{1, 1, 1}};
    for (const pm::Vec3& x : pts) {
      double v = 0;
      if (h.sample(x, v) && !(v >= 0)) {  // positive voxels, weights >= 0 summing to 1
        std::fprintf(stderr, "fuzz: sizing field sampled h = %g from positive voxels\n", v);
        std::abort();
      }
    }
  });
  return 0;
}
