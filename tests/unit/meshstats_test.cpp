#include "pm/mesh/meshstats.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <cmath>

#include "pm/base/error.h"
#include "pm/field/implicits.h"
#include "test_meshes.h"

namespace pm {
namespace {

Mesh icosahedron() {
  const double t = (1 + std::sqrt(5.0)) / 2;
  Mesh m;
  m.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (Vec3& v : m.vertices) v = normalized(v);
  m.faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  return m;
}

TEST(MeshStats, RegularIcosahedron) {
  const auto sphere = make_implicit("sphere");
  MeshQualityParams p;
  p.field = sphere.get();
  const MeshQuality q = mesh_quality(icosahedron(), p);
  EXPECT_NEAR(q.rr_min, 1.0, 1e-12);
  EXPECT_NEAR(q.rr_mean, 1.0, 1e-12);
  EXPECT_NEAR(q.min_angle_deg, 60.0, 1e-9);
  EXPECT_EQ(q.valence_histogram[5], 12u);
  EXPECT_DOUBLE_EQ(q.valence6_share, 0.0);
  EXPECT_DOUBLE_EQ(q.valence_outside_5_7_share, 0.0);
  EXPECT_EQ(q.topology.genus, 0);
  EXPECT_EQ(q.topology.components, 1u);
  EXPECT_EQ(q.self_intersecting_pairs, 0);
  EXPECT_LT(q.dist_vertex_max, 1e-12);
  // Face centroid of the unit icosahedron lies at the inradius 0.7947 from the centre.
  const double inradius = std::sqrt(3.0) / 12 * (3 + std::sqrt(5.0)) * (4 / std::sqrt(10 + 2 * std::sqrt(5.0)));
  EXPECT_NEAR(q.dist_centroid_max, 1 - inradius, 1e-6);
  EXPECT_TRUE(check_requirements(q, "rr_min>=0.99,watertight,manifold,genus=0,no_self_intersections").empty());
  const auto failed = check_requirements(q, "valence6>=0.65, rr_mean>=0.5");
  ASSERT_EQ(failed.size(), 1u);
  EXPECT_NE(failed[0].find("valence6"), std::string::npos);
  EXPECT_THROW(check_requirements(q, "bogus>=1"), UsageError);
  EXPECT_THROW(check_requirements(q, "nonsense"), UsageError);
}

// The mean edge length is summed over the edges in the order the faces first
// name them (not the order of a hash set, which differs between standard
// libraries): bit for bit that sum, on a sphere with jittered vertices.
TEST(MeshStats, EdgeMeanSumsInFaceOrder) {
  Mesh m = testing::icosphere(3);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.01, 0.01);
  for (Vec3& v : m.vertices) v += Vec3{jitter(rng), jitter(rng), jitter(rng)};
  double sum = 0;
  std::size_t count = 0;
  std::vector<std::pair<int, int>> seen;
  for (const auto& f : m.faces)
    for (int e = 0; e < 3; ++e) {
      const std::pair<int, int> ab = std::minmax(int(f[e]), int(f[(e + 1) % 3]));
      if (std::find(seen.begin(), seen.end(), ab) != seen.end()) continue;
      seen.push_back(ab);
      sum += norm(m.vertices[ab.first] - m.vertices[ab.second]);
      ++count;
    }
  ASSERT_EQ(count, m.faces.size() * 3 / 2);
  EXPECT_EQ(mesh_quality(m).edge_length_mean, sum / double(count));
}

TEST(MeshStats, DegenerateAndOpenAndIntersecting) {
  Mesh m = icosahedron();
  m.faces.pop_back();
  MeshQuality q = mesh_quality(m);
  EXPECT_EQ(q.topology.boundary_edges, 3u);
  EXPECT_EQ(q.topology.genus, -1);
  EXPECT_EQ(check_requirements(q, "watertight").size(), 1u);

  Mesh flat;
  flat.vertices = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  flat.faces = {{0, 1, 2}};
  EXPECT_NEAR(mesh_quality(flat).rr_min, 0.0, 1e-12);

  // Two interpenetrating icosahedra.
  Mesh two = icosahedron();
  const Mesh b = icosahedron();
  for (const Vec3& v : b.vertices) two.vertices.push_back(v + Vec3(0.5, 0.1, 0.05));
  for (const auto& f : b.faces) two.faces.push_back({f[0] + 12, f[1] + 12, f[2] + 12});
  q = mesh_quality(two);
  EXPECT_EQ(q.topology.components, 2u);
  EXPECT_GT(q.self_intersecting_pairs, 0);
}

TEST(MeshStats, SelfIntersectionsAreCgalsPairForPair) {
  // The grid search for candidate pairs against CGAL's own
  // PMP::self_intersections (its box search), pair for pair, on meshes with
  // many crossings: interpenetrating spheres, a sphere crumpled by noise
  // (crossings between neighbouring faces too), exactly coplanar overlapping
  // faces (two cubes, one resting on the other's top, shifted), a collinear
  // (degenerate) face, and an intact surface (none).
  std::vector<std::pair<std::string, Mesh>> cases;
  Mesh two = testing::icosphere(3, 1.0);
  const Mesh b = testing::icosphere(3, 0.8, {0.9, 0.13, -0.07});
  const int nv = int(two.vertices.size());
  for (const Vec3& v : b.vertices) two.vertices.push_back(v);
  for (const auto& f : b.faces) two.faces.push_back({f[0] + nv, f[1] + nv, f[2] + nv});
  cases.emplace_back("two spheres", two);
  Mesh crumpled = testing::icosphere(3, 1.0);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.09, 0.09);
  for (Vec3& v : crumpled.vertices) v = v + Vec3(u(rng), u(rng), u(rng));
  cases.emplace_back("crumpled sphere", crumpled);
  auto cube = [](Vec3 lo, double s) {
    Mesh c;
    for (int k = 0; k < 8; ++k) c.vertices.push_back(lo + Vec3((k & 1) * s, ((k >> 1) & 1) * s, ((k >> 2) & 1) * s));
    c.faces = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
               {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    return c;
  };
  Mesh stacked = cube({0, 0, 0}, 1);
  const Mesh top = cube({0.5, 0.25, 1}, 1);  // its bottom lies in the plane of the first's top
  for (const Vec3& v : top.vertices) stacked.vertices.push_back(v);
  for (const auto& f : top.faces) stacked.faces.push_back({f[0] + 8, f[1] + 8, f[2] + 8});
  cases.emplace_back("stacked cubes", stacked);
  Mesh flat = cube({0, 0, 0}, 1);
  flat.vertices[4] = {0.5, 0, 0};  // face {0, 1, 4} collinear (exactly: halves are exact)
  cases.emplace_back("collinear face", flat);
  cases.emplace_back("intact sphere", testing::icosphere(4, 1.0));
  // Two small interpenetrating spheres inside a cell of a grid sized by a
  // huge coarse one: too crowded for the grid, CGAL's own search then.
  Mesh crowd = testing::icosphere(1, 100.0);
  for (const Vec3& c : {Vec3(0, 0, 0), Vec3(0.01, 0.002, 0)}) {
    const Mesh t = testing::icosphere(3, 0.008, c);
    const int base = int(crowd.vertices.size());
    for (const Vec3& v : t.vertices) crowd.vertices.push_back(v);
    for (const auto& f : t.faces) crowd.faces.push_back({f[0] + base, f[1] + base, f[2] + base});
  }
  cases.emplace_back("crowded cell", crowd);
  std::size_t total = 0;
  for (const auto& [name, mesh] : cases) {
    std::vector<std::pair<int, int>> ours, cgal;
    ASSERT_TRUE(self_intersecting_faces(mesh, ours)) << name;
    ASSERT_TRUE(detail::cgal_self_intersecting_faces(mesh, cgal)) << name;
    EXPECT_EQ(ours, cgal) << name << ": " << ours.size() << " pairs against CGAL's " << cgal.size();
    if (name == "intact sphere") EXPECT_TRUE(ours.empty());
    else EXPECT_FALSE(ours.empty()) << name;
    total += ours.size();
  }
  EXPECT_GT(total, 100u);
}

TEST(MeshStats, EdgeOverSizing) {
  // Icosahedron edge of the unit-circumradius icosahedron is 1.0515; with h = 0.6 every edge is < 2h.
  MeshQualityParams p;
  const SizingField h = SizingField::constant(0.6, Box{{-2, -2, -2}, {2, 2, 2}});
  p.sizing = &h;
  const MeshQuality q = mesh_quality(icosahedron(), p);
  EXPECT_NEAR(q.edge_h_max, 1.0514622 / 0.6, 1e-6);
  EXPECT_DOUBLE_EQ(q.edge_le_2h_share, 1.0);
  const SizingField h2 = SizingField::constant(0.5, Box{{-2, -2, -2}, {2, 2, 2}});
  p.sizing = &h2;
  EXPECT_DOUBLE_EQ(mesh_quality(icosahedron(), p).edge_le_2h_share, 0.0);
}

}  // namespace
}  // namespace pm
