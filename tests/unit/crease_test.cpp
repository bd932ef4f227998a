// crease_share_20 (meshstats): the share of interior edges whose two faces bend by
// more than 20 degrees, on meshes whose dihedral angles are known exactly.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <utility>

#include "pm/mesh/meshstats.h"
#include "pm/mesh/meshstats_materials.h"
#include "test_meshes.h"

namespace pm {
namespace {

// Unit cube, 12 triangles wound outward: 12 cube edges at 90 degrees, 6 face diagonals flat.
Mesh cube(Vec3 shift = {}) {
  Mesh m;
  for (int k = 0; k < 8; ++k) m.vertices.push_back(Vec3{double(k & 1), double((k >> 1) & 1), double(k >> 2)} + shift);
  m.faces = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
             {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return m;
}

// Two triangles sharing the edge (0,0,0)-(0,1,0), the second bent by `deg` degrees.
Mesh hinge(double deg) {
  const double a = deg * M_PI / 180;
  Mesh m;
  m.vertices = {{0, 0, 0}, {0, 1, 0}, {-1, 0.5, 0}, {std::cos(a), 0.5, std::sin(a)}};
  m.faces = {{0, 1, 2}, {1, 0, 3}};
  return m;
}

TEST(Crease, CubeEdgesBendNinetyDegrees) {
  const Mesh m = cube();
  const CreaseCount c = count_creases(m);
  EXPECT_EQ(c.interior_edges, 18u);  // 12 cube edges + 6 face diagonals
  EXPECT_EQ(c.creased, 12u);
  const MeshQuality q = mesh_quality(m);
  EXPECT_DOUBLE_EQ(q.crease_share_20, 12.0 / 18.0);
  EXPECT_EQ(check_requirements(q, "crease_share_20<=0.03").size(), 1u);
  EXPECT_TRUE(check_requirements(q, "crease_share_20<=0.7").empty());
  // A 90-degree bend is a crease for any threshold below 90 and none above.
  EXPECT_EQ(count_creases(m, {}, 89.9).creased, 12u);
  EXPECT_EQ(count_creases(m, {}, 90.1).creased, 0u);
}

TEST(Crease, OrientationDoesNotMatter) {
  Mesh m = cube();
  std::swap(m.faces[3][1], m.faces[3][2]);  // one face wound inward
  std::swap(m.faces[8][1], m.faces[8][2]);
  const CreaseCount c = count_creases(m);
  EXPECT_EQ(c.interior_edges, 18u);
  EXPECT_EQ(c.creased, 12u);
}

TEST(Crease, FineSphereHasNone) {
  // Level 4: 5120 faces, 7680 edges; neighbouring normals differ by about the edge's
  // angle seen from the centre, ~3.6 degrees, far below 20.
  const Mesh m = testing::icosphere(4);
  const MeshQuality q = mesh_quality(m);
  EXPECT_EQ(q.interior_edges, 7680u);
  EXPECT_EQ(q.creased_edges_20, 0u);
  EXPECT_DOUBLE_EQ(q.crease_share_20, 0.0);
  // The bare icosahedron bends 41.8 degrees at each of its 30 edges.
  EXPECT_EQ(count_creases(testing::icosphere(0)).creased, 30u);
}

TEST(Crease, ThresholdIsTwentyDegrees) {
  EXPECT_EQ(count_creases(hinge(19)).creased, 0u);
  EXPECT_EQ(count_creases(hinge(21)).creased, 1u);
  EXPECT_EQ(count_creases(hinge(21)).interior_edges, 1u);
  // Open edges (one face) and a degenerate face are not interior edges.
  Mesh h = hinge(40);
  h.vertices[3] = {0, 0.5, 0};  // on the shared edge: zero area
  EXPECT_EQ(count_creases(h).interior_edges, 0u);
}

TEST(Crease, InterfaceMeshPerPairAndPooled) {
  // Pair (0,1): a cube (12 creases of 18 interior edges); pair (1,2): a fine sphere
  // far away (none of 7680). Pooled: 12 / 7698.
  Mesh m = cube({5, 0, 0});
  const Mesh s = testing::icosphere(4);
  const int off = int(m.vertices.size());
  m.vertices.insert(m.vertices.end(), s.vertices.begin(), s.vertices.end());
  for (auto f : s.faces) m.faces.push_back({f[0] + off, f[1] + off, f[2] + off});
  auto& a = m.face_ints["label_a"];
  auto& b = m.face_ints["label_b"];
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    a.push_back(f < 12 ? 0 : 1);
    b.push_back(f < 12 ? 1 : 2);
  }
  const InterfaceQuality q = interface_quality(m);
  ASSERT_EQ(q.pair_creases.size(), 2u);
  EXPECT_EQ(q.pair_creases.at({0, 1}).creased, 12u);
  EXPECT_EQ(q.pair_creases.at({0, 1}).interior_edges, 18u);
  EXPECT_EQ(q.pair_creases.at({1, 2}).creased, 0u);
  EXPECT_DOUBLE_EQ(q.overall.crease_share_20, 12.0 / 7698.0);
  const Json j = to_json(q);
  EXPECT_DOUBLE_EQ(j["interfaces"]["crease_share_20"].get<double>(), 12.0 / 7698.0);
  EXPECT_EQ(j["interfaces"]["per_pair"].size(), 2u);
  EXPECT_TRUE(check_interface_requirements(q, "crease_share_20<=0.002").empty());
  EXPECT_EQ(check_interface_requirements(q, "crease_share_20<=0.001").size(), 1u);
}

}  // namespace
}  // namespace pm
