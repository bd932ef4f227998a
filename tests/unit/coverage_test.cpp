#include "pm/mesh/coverage.h"

#include <gtest/gtest.h>

#include <cmath>

#include "pm/base/error.h"

namespace pm {
namespace {

// Seeds on two spheres (components 0 and 1) of radius 1 centred 3 apart.
Mesh two_sphere_seeds() {
  Mesh s;
  std::vector<double> comp;
  for (int c = 0; c < 2; ++c)
    for (int i = 0; i < 200; ++i) {
      const double z = -1 + 2 * (i + 0.5) / 200, phi = 2.39996 * i, r = std::sqrt(1 - z * z);
      s.vertices.push_back({3.0 * c + r * std::cos(phi), r * std::sin(phi), z});
      comp.push_back(c);
    }
  s.vertex_scalars["component"] = comp;
  return s;
}

TEST(Coverage, FindsTheMissedComponent) {
  const Mesh seeds = two_sphere_seeds();
  // Points on the first sphere only, slightly off the seeds.
  std::vector<Vec3> pts;
  for (int i = 0; i < 50; ++i) {
    const double z = -0.9 + 1.8 * i / 49, r = std::sqrt(1 - z * z);
    pts.push_back({r * std::cos(i), r * std::sin(i), z});
  }
  auto cov = component_coverage(seeds, pts);
  ASSERT_EQ(cov.size(), 2u);
  EXPECT_EQ(cov[0].points, 50u);
  EXPECT_EQ(cov[1].points, 0u);
  EXPECT_EQ(cov[1].seeds, 200u);
  EXPECT_NEAR(cov[1].bounds.lo.x, 2.0, 0.05);
  // A point far outside the seeds' box still finds its nearest seed.
  pts.push_back({100, 0, 0});
  cov = component_coverage(seeds, pts);
  EXPECT_EQ(cov[1].points, 1u);
}

TEST(Coverage, BadSeeds) {
  Mesh s = two_sphere_seeds();
  s.vertex_scalars.clear();
  EXPECT_THROW(component_coverage(s, {}), InputError);
  EXPECT_THROW(component_coverage(Mesh{}, {}), InputError);
}

}  // namespace
}  // namespace pm
