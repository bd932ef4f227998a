#include "pm/field/mesh_sdf.h"

#include <gtest/gtest.h>

#include <cmath>

#include "pm/base/error.h"
#include "test_meshes.h"

namespace pm {
namespace {

TEST(MeshSdf, SphereDistanceWithinOneVoxel) {
  const double R = 1.0, h = 0.05;
  const Mesh m = testing::icosphere(4, R);  // 5120 faces: chord error ~ R(1-cos(θ/2)) < 0.003
  ASSERT_TRUE(check_closed(m).closed());
  MeshSdfParams p;
  p.voxel = h;
  const Volume d = mesh_to_sdf(m, p);
  EXPECT_NEAR(d.geometry().spacing(0), h, 1e-12);
  double worst = 0;
  std::size_t inside = 0;
  for (std::size_t k = 0; k < d.dims().nz; ++k)
    for (std::size_t j = 0; j < d.dims().ny; ++j)
      for (std::size_t i = 0; i < d.dims().nx; ++i) {
        const Vec3 x = d.geometry().index_to_world(Vec3(double(i), double(j), double(k)));
        const double exact = norm(x) - R;
        worst = std::max(worst, std::fabs(d.get(i, j, k) - exact));
        inside += d.get(i, j, k) < 0;
      }
  EXPECT_LT(worst, h) << "max |d - (|x| - R)| over the whole box";
  // Inside voxel count ≈ sphere volume / h³ (5%).
  EXPECT_NEAR(double(inside), 4.0 / 3.0 * M_PI / (h * h * h), 0.05 * 4.0 / 3.0 * M_PI / (h * h * h));
}

TEST(MeshSdf, NarrowBandClamps) {
  MeshSdfParams p;
  p.voxel = 0.1;
  p.band = 2;
  const Volume d = mesh_to_sdf(testing::icosphere(3, 1.0), p);
  const ValueRange r = value_range(d);
  EXPECT_LE(r.hi, 2 * 0.1 + 1e-6);
  EXPECT_GE(r.lo, -2 * 0.1 - 1e-6);
}

TEST(MeshSdf, RejectsOpenMeshAndBadVoxel) {
  Mesh m = testing::icosphere(1, 1.0);
  m.faces.pop_back();
  EXPECT_EQ(check_closed(m).boundary_edges, 3u);
  MeshSdfParams p;
  p.voxel = 0.1;
  EXPECT_THROW(mesh_to_sdf(m, p), InputError);
  p.voxel = 0;
  EXPECT_THROW(mesh_to_sdf(testing::icosphere(1, 1.0), p), UsageError);
  p.voxel = 1e-6;
  EXPECT_THROW(mesh_to_sdf(testing::icosphere(1, 1.0), p), InputError);  // grid too large
}

}  // namespace
}  // namespace pm
