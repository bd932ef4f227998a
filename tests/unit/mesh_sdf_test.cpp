#include "pm/field/mesh_sdf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "pm/base/error.h"

namespace pm {
namespace {

// Icosphere of radius R: subdivided icosahedron projected to the sphere.
Mesh icosphere(double R, int levels) {
  const double t = (1 + std::sqrt(5.0)) / 2;
  Mesh m;
  m.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  m.faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      m.vertices.push_back((m.vertices[a] + m.vertices[b]) * 0.5);
      return mid[key] = int(m.vertices.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& f : m.faces) {
      const int a = midpoint(f[0], f[1]), b = midpoint(f[1], f[2]), c = midpoint(f[2], f[0]);
      next.push_back({f[0], a, c});
      next.push_back({f[1], b, a});
      next.push_back({f[2], c, b});
      next.push_back({a, b, c});
    }
    m.faces = next;
  }
  for (Vec3& v : m.vertices) v = normalized(v) * R;
  return m;
}

TEST(MeshSdf, SphereDistanceWithinOneVoxel) {
  const double R = 1.0, h = 0.05;
  const Mesh m = icosphere(R, 4);  // 5120 faces: chord error ~ R(1-cos(θ/2)) < 0.003
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
  const Volume d = mesh_to_sdf(icosphere(1.0, 3), p);
  const ValueRange r = value_range(d);
  EXPECT_LE(r.hi, 2 * 0.1 + 1e-6);
  EXPECT_GE(r.lo, -2 * 0.1 - 1e-6);
}

TEST(MeshSdf, RejectsOpenMeshAndBadVoxel) {
  Mesh m = icosphere(1.0, 1);
  m.faces.pop_back();
  EXPECT_EQ(check_closed(m).boundary_edges, 3u);
  MeshSdfParams p;
  p.voxel = 0.1;
  EXPECT_THROW(mesh_to_sdf(m, p), InputError);
  p.voxel = 0;
  EXPECT_THROW(mesh_to_sdf(icosphere(1.0, 1), p), UsageError);
  p.voxel = 1e-6;
  EXPECT_THROW(mesh_to_sdf(icosphere(1.0, 1), p), InputError);  // grid too large
}

}  // namespace
}  // namespace pm
