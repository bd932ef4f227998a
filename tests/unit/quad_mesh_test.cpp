// Quad-dominant meshes (pm/mesh/quad_mesh.h, issue #20): a checkerboard-typed
// triangulated grid must come back as exact unit squares; a cube's surface
// keeps its topology (V - E + F = 2); bad input is refused.
#include "pm/mesh/quad_mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>

#include "pm/base/error.h"
#include "pm/baseline/gmsh_recombine.h"
#include "pm/io/poly_mesh.h"
#include "pm/mesh/quad_smooth.h"
#include "test_fields.h"

namespace pm {
namespace {

// The closed surface of an n x n x n cube of unit cells, each square split
// along a diagonal between like corners of the checkerboard type
// (i + j + k) % 2, so dropping like edges recovers every square.
Mesh checker_cube(int n, std::vector<int>& type) {
  Mesh m;
  std::map<std::array<int, 3>, int> id;
  auto vid = [&](int i, int j, int k) {
    const auto it = id.find({i, j, k});
    if (it != id.end()) return it->second;
    const int v = int(m.vertices.size());
    id[{i, j, k}] = v;
    m.vertices.push_back(Vec3(i, j, k));
    type.push_back((i + j + k) % 2);
    return v;
  };
  // A face square with corners c0..c3 counter-clockwise seen from outside.
  auto square = [&](std::array<int, 3> c0, std::array<int, 3> du, std::array<int, 3> dv) {
    auto at = [&](int a, int b) { return vid(c0[0] + a * du[0] + b * dv[0], c0[1] + a * du[1] + b * dv[1], c0[2] + a * du[2] + b * dv[2]); };
    const int p0 = at(0, 0), p1 = at(1, 0), p2 = at(1, 1), p3 = at(0, 1);
    // Split along the diagonal whose ends have the same type: p0-p2 are like.
    m.faces.push_back({p0, p1, p2});
    m.faces.push_back({p0, p2, p3});
  };
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      square({a, b, 0}, {0, 1, 0}, {1, 0, 0});      // z = 0, outward -z
      square({a, b, n}, {1, 0, 0}, {0, 1, 0});      // z = n, +z
      square({a, 0, b}, {1, 0, 0}, {0, 0, 1});      // y = 0, -y
      square({a, n, b}, {0, 0, 1}, {1, 0, 0});      // y = n, +y
      square({0, a, b}, {0, 0, 1}, {0, 1, 0});      // x = 0, -x
      square({n, a, b}, {0, 1, 0}, {0, 0, 1});      // x = n, +x
    }
  return m;
}

TEST(QuadMesh, CheckerboardCubeGivesEverySquare) {
  std::vector<int> type;
  const Mesh m = checker_cube(4, type);
  const QuadResult r = quad_dominant(m, type);
  EXPECT_EQ(r.like_merges, 6u * 16);
  EXPECT_EQ(r.leftover_merges, 0u);
  EXPECT_EQ(r.triangles_left, 0u);
  const QuadQuality q = quad_quality(r.mesh);
  EXPECT_EQ(q.quads, 96u);
  EXPECT_DOUBLE_EQ(q.quad_share(), 1.0);
  EXPECT_NEAR(q.corner_min, 90.0, 1e-9);
  EXPECT_NEAR(q.corner_max, 90.0, 1e-9);
  EXPECT_DOUBLE_EQ(q.corner_share_70_110(), 1.0);
  EXPECT_NEAR(q.jacobian_min, 1.0, 1e-12);  // squares, outward
  EXPECT_EQ(q.boundary_edges, 0u);
  EXPECT_EQ(q.nonmanifold_edges, 0u);
  // Valence: 8 cube corners have 3 edges, every other vertex 4.
  EXPECT_EQ(q.irregular, 8u);
  EXPECT_EQ(q.valence4, q.vertices - 8);
  // Euler characteristic of the sphere: V - E + F = 2, E = 4 F / 2 for quads.
  EXPECT_EQ(long(q.vertices) - long(2 * q.quads) + long(q.quads), 2);
}

TEST(QuadMesh, LeftoversPairAcrossUnlikeEdgesOrStay) {
  // A type defect at a cube corner: the triangles around it have no like
  // diagonal to drop; they pair across unlike edges where the quad is good
  // enough, or stay triangles. Either way every triangle is used once and the
  // mesh stays closed.
  std::vector<int> type;
  const Mesh m = checker_cube(2, type);
  std::vector<int> flipped = type;
  flipped[0] = 1 - flipped[0];  // a defect: vertex (0,0,0) has the wrong type
  QuadParams p;
  const QuadResult r = quad_dominant(m, flipped, p);
  const QuadQuality q = quad_quality(r.mesh);
  EXPECT_EQ(q.boundary_edges, 0u);
  EXPECT_EQ(q.nonmanifold_edges, 0u);
  EXPECT_GT(r.leftover_merges + r.triangles_left, 0u);  // the defect shows
  EXPECT_EQ(2 * q.quads + q.triangles, m.faces.size());  // every triangle is used once
  p.pair_leftovers = false;
  const QuadResult s = quad_dominant(m, flipped, p);
  EXPECT_EQ(s.leftover_merges, 0u);
  EXPECT_GE(s.triangles_left, r.triangles_left);
}

// Four triangles in a strip A - B - C - D (each shares an edge with the
// next), all vertices of one type (every edge a like edge). B and C form
// the unit square, the best quad, so the greedy matching takes it first and
// leaves A and D alone; the augmenting path A - B = C - D re-pairs them into
// two quads (A, B) and (C, D). Their worst corner is B's 45° at (1, 1), so
// they may be used with augment_max_deviation 60 but not with the default 40.
TEST(QuadMesh, AugmentingPathsPairWhatTheGreedyLeft) {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, -0.6, 0}, {0.5, 1.6, 0}};
  m.faces = {{0, 4, 1}, {0, 1, 2}, {0, 2, 3}, {3, 2, 5}};  // A, B, C, D (counter-clockwise)
  const std::vector<int> type(m.vertices.size(), 0);
  QuadParams p;
  p.augment_depth = 0;
  const QuadResult greedy = quad_dominant(m, type, p);
  EXPECT_EQ(greedy.mesh.quad_count(), 1u);
  EXPECT_EQ(greedy.triangles_left, 2u);
  p.augment_depth = 3;
  EXPECT_EQ(quad_dominant(m, type, p).augmented, 0u);  // default: corners within 40° only
  p.augment_max_deviation = 60;
  const QuadResult r = quad_dominant(m, type, p);
  EXPECT_EQ(r.augmented, 1u);
  EXPECT_EQ(r.mesh.quad_count(), 2u);
  EXPECT_EQ(r.triangles_left, 0u);
  EXPECT_EQ(r.like_merges + r.leftover_merges, 2u);
  const QuadQuality q = quad_quality(r.mesh);
  EXPECT_LE(q.corner_max, 90 + p.max_corner_deviation);
  EXPECT_GE(q.corner_min, 90 - p.max_corner_deviation);
}

TEST(QuadMesh, FoldsAreNotMerged) {
  // Two triangles of a tetrahedron meet at 70.5 degrees between faces (a fold of
  // 109.5 degrees between normals): never one quad.
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  const QuadResult r = quad_dominant(m, {0, 0, 1, 1});
  EXPECT_EQ(r.like_merges + r.leftover_merges, 0u);
  EXPECT_EQ(r.triangles_left, 4u);
}

TEST(QuadMesh, BadInputIsRefused) {
  std::vector<int> type;
  Mesh m = checker_cube(1, type);
  type.pop_back();
  EXPECT_THROW(quad_dominant(m, type), InputError);
  type.push_back(0);
  m.faces.push_back(m.faces[0]);  // an edge in three triangles
  EXPECT_THROW(quad_dominant(m, type), InputError);
  PolyMesh bad;
  bad.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  bad.faces = {{0, 1, 1, -1}};
  EXPECT_THROW(quad_quality(bad), InputError);
}

TEST(QuadMesh, PolygonFilesReadBackWithTheirQuads) {
  std::vector<int> type;
  const QuadResult r = quad_dominant(checker_cube(2, type), type);
  ASSERT_GT(r.mesh.quad_count(), 0u);
  PolyMesh mixed = r.mesh;  // one quad split into two triangles: a mixed mesh
  const auto q = mixed.faces[0];
  mixed.faces[0] = {q[0], q[1], q[2], -1};
  mixed.faces.push_back({q[0], q[2], q[3], -1});
  const std::string dir = ::testing::TempDir();
  for (const char* ext : {".ply", ".obj", ".off"}) {
    for (bool binary : {true, false}) {
      SCOPED_TRACE(std::string(ext) + (binary ? " binary" : " ascii"));
      const std::string path = dir + "/pm_quads" + ext;
      write_poly_mesh(mixed, path, WorldFrame::lps, binary);
      const PolyMesh back = read_poly_mesh(path);
      ASSERT_EQ(back.faces, mixed.faces);
      ASSERT_EQ(back.vertices.size(), mixed.vertices.size());
      for (std::size_t i = 0; i < back.vertices.size(); ++i) EXPECT_EQ(norm(back.vertices[i] - mixed.vertices[i]), 0.0);
      std::remove(path.c_str());
    }
  }
  // A pentagon is neither: refused, naming the file and the polygon.
  const std::string off = dir + "/pm_pentagon.off";
  std::ofstream(off) << "OFF\n5 1 0\n0 0 0\n1 0 0\n1.3 1 0\n0.5 1.6 0\n-0.3 1 0\n5 0 1 2 3 4\n";
  try {
    read_poly_mesh(off);
    ADD_FAILURE() << "pentagon accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("pm_pentagon.off\": polygon 0 has 5 vertices; expected triangles and quads"),
              std::string::npos)
        << e.what();
  }
  std::remove(off.c_str());
  EXPECT_THROW(read_poly_mesh(dir + "/pm_quads.stl"), UsageError);
}

// The Gmsh baseline on the triangulated cube: every square is two triangles
// across a diagonal, a perfect matching exists (pair each square's two
// triangles), and Blossom, a minimum-cost perfect matching on quad quality,
// must find exactly it: 96 unit squares, the vertices kept in place, each
// directed edge once (the input's orientation), the cube's 8 valence-3 corners.
TEST(QuadMesh, GmshBlossomRecombinesTheCubeIntoItsSquares) {
  std::vector<int> type;
  const Mesh m = checker_cube(4, type);
  const GmshRecombineResult g = gmsh_recombine(m);
  EXPECT_FALSE(g.gmsh_version.empty());
  ASSERT_EQ(g.mesh.vertices.size(), m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) EXPECT_EQ(norm(g.mesh.vertices[i] - m.vertices[i]), 0.0) << i;
  const QuadQuality q = quad_quality(g.mesh);
  EXPECT_EQ(q.quads, 96u);
  EXPECT_EQ(q.triangles, 0u);
  EXPECT_NEAR(q.corner_min, 90.0, 1e-9);
  EXPECT_NEAR(q.corner_max, 90.0, 1e-9);
  EXPECT_NEAR(q.jacobian_min, 1.0, 1e-12);  // outward, as the input
  EXPECT_EQ(q.boundary_edges, 0u);
  EXPECT_EQ(q.nonmanifold_edges, 0u);
  EXPECT_EQ(q.irregular, 8u);
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : g.mesh.faces)
    for (int k = 0; k < 4; ++k) ++directed[{f[std::size_t(k)], f[std::size_t((k + 1) % 4)]}];
  for (const auto& [e, count] : directed) {
    EXPECT_EQ(count, 1) << e.first << " -> " << e.second;
    EXPECT_EQ(directed.count({e.second, e.first}), 1u) << e.first << " -> " << e.second;
  }
  // The simple (greedy) algorithm may leave triangles but uses each once.
  GmshRecombineParams simple;
  simple.algorithm = 0;
  const QuadQuality s = quad_quality(gmsh_recombine(m, simple).mesh);
  EXPECT_EQ(2 * s.quads + s.triangles, m.faces.size());
  EXPECT_EQ(s.boundary_edges, 0u);
  Mesh empty;
  EXPECT_THROW(gmsh_recombine(empty), InputError);
}


// The cube's squares pushed onto a sphere about its centre (vertices
// normalised): quads near the cube's edges and corners are skewed. Smoothing on the sphere must lower the corner objective
// (a move is kept only when it does), keep every vertex on the sphere to the
// projection tolerance, keep the faces, and keep every quad's scaled Jacobian
// above min(its value before, 0.3); away from the 8 valence-3 corners, whose
// three corners must share about 360° plus the spherical excess, the worst
// corner must come closer to 90°.
TEST(QuadSmooth, CubeSphereCornersComeCloserToRightAngles) {
  const int n = 6;
  std::vector<int> type;
  const QuadResult r = quad_dominant(checker_cube(n, type), type);
  PolyMesh m = r.mesh;
  const Vec3 c(n / 2.0, n / 2.0, n / 2.0);
  for (Vec3& v : m.vertices) v = c + normalized(v - c) * 3.0;
  const test::Ball f(c, 3.0, 6.0);
  const QuadQuality before = quad_quality(m);
  std::vector<double> jac_before;
  auto jacobians = [](const PolyMesh& q) {
    std::vector<double> j;
    for (const auto& face : q.faces) j.push_back(polygon_scaled_jacobian(q.vertices, face));
    return j;
  };
  jac_before = jacobians(m);
  // Worst deviation from 90° over corners at valence-4 vertices.
  auto worst_regular = [](const PolyMesh& q) {
    std::vector<int> valence(q.vertices.size(), 0);
    for (const auto& face : q.faces)
      for (int k = 0; k < 4; ++k) ++valence[std::size_t(face[std::size_t(k)])];  // faces = edges on a closed quad mesh
    double worst = 0;
    for (const auto& face : q.faces)
      for (int k = 0; k < 4; ++k) {
        if (valence[std::size_t(face[std::size_t(k)])] != 4) continue;
        const Vec3 &p = q.vertices[std::size_t(face[std::size_t((k + 3) % 4)])], &v = q.vertices[std::size_t(face[std::size_t(k)])],
                   &nx = q.vertices[std::size_t(face[std::size_t((k + 1) % 4)])];
        const double cs = dot(normalized(p - v), normalized(nx - v));
        worst = std::max(worst, std::fabs(std::acos(std::clamp(cs, -1.0, 1.0)) * 57.29577951308232 - 90));
      }
    return worst;
  };
  const double worst_before = worst_regular(m);
  QuadSmoothParams sp;
  sp.passes = 20;
  const QuadSmoothStats st = smooth_quads(m, f, 0.0, sp);
  EXPECT_GT(st.moves, 0u);
  EXPECT_LT(st.objective_after, st.objective_before);
  ASSERT_EQ(m.faces, r.mesh.faces);
  const double edge = 3.0 * 1.5708 / n;  // about a quarter great circle over n
  for (const Vec3& v : m.vertices) EXPECT_LE(std::fabs(norm(v - c) - 3.0), 1e-6 * edge * 1.01);
  const std::vector<double> jac_after = jacobians(m);
  for (std::size_t i = 0; i < jac_after.size(); ++i)
    EXPECT_GE(jac_after[i], std::min(jac_before[i], sp.min_jacobian) - 1e-12) << i;
  const QuadQuality after = quad_quality(m);
  EXPECT_GE(after.corner_share_70_110(), before.corner_share_70_110());
  EXPECT_LT(worst_regular(m), worst_before);
  EXPECT_EQ(after.irregular, 8u);
  // Without passes nothing moves.
  PolyMesh same = r.mesh;
  sp.passes = 0;
  smooth_quads(same, f, 0.0, sp);
  EXPECT_EQ(same.vertices, r.mesh.vertices);
}

}  // namespace
}  // namespace pm
