// The particle-seed input of `particles --init FILE`: a PLY point set read
// with pm::read_mesh whose vertices start the particle system. Small seed
// sets (<= 16 points) are also fed to one sweep of the system on the unit
// sphere, which checks them (non-finite coordinates) and projects them.
#include "fuzz_util.h"
#include "pm/field/implicits.h"
#include "pm/io/mesh.h"
#include "pm/sample/particles.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::unique_ptr<pm::ScalarField> sphere = pm::make_implicit("sphere");
  const std::string path = pm::fuzz::put_file("seeds.ply", data, size);
  pm::fuzz::expect_pm_errors_only([&] {
    const std::vector<pm::Vec3> seeds = pm::read_mesh(path).vertices;
    if (seeds.empty() || seeds.size() > 16) return;
    pm::ParticleParams p;
    p.spacing = 0.8;
    p.max_iters = 1;
    p.population_control = false;
    p.progress = false;
    pm::distribute_particles(*sphere, seeds, nullptr, p);
  });
  return 0;
}
