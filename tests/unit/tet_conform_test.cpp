// Conforming tetrahedralisation (pm/mesh/tet_conform.h): generated icospheres
// and boxes, meshed with lattice points inside; the boundary must come back
// exactly, the volume must be the polyhedron's (exact for a polyhedron up to
// rounding), and bad surfaces are refused with their counts.
#include "pm/mesh/tet_conform.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "pm/base/error.h"
#include "pm/mesh/meshstats.h"
#include "test_meshes.h"

namespace pm {
namespace {

using testing::icosphere;

// Signed volume enclosed by outward triangles (divergence theorem).
double enclosed_volume(const Mesh& m) {
  double v = 0;
  for (const auto& f : m.faces)
    v += dot(m.vertices[std::size_t(f[0])], cross(m.vertices[std::size_t(f[1])], m.vertices[std::size_t(f[2])]));
  return v / 6;
}

double tets_volume(const LabelledTets& t, int material = -1) {
  double v = 0;
  for (std::size_t i = 0; i < t.tets.size(); ++i) {
    if (material >= 0 && t.materials[i] != material) continue;
    const auto& q = t.tets[i];
    const Vec3 &a = t.vertices[std::size_t(q[0])], &b = t.vertices[std::size_t(q[1])],
               &c = t.vertices[std::size_t(q[2])], &d = t.vertices[std::size_t(q[3])];
    v += dot(b - a, cross(c - a, d - a)) / 6;
  }
  return v;
}

// Body-centred cubic lattice of spacing h inside the ball |x| < r, at least
// `gap` from the spheres |x| = r and |x| = hole (hole 0: none).
std::vector<Vec3> bcc_ball(double r, double h, double gap, double hole = 0) {
  std::vector<Vec3> p;
  const int n = int(std::ceil(r / h));
  for (int i = -n; i <= n; ++i)
    for (int j = -n; j <= n; ++j)
      for (int k = -n; k <= n; ++k)
        for (int o = 0; o < 2; ++o) {
          const Vec3 x{(i + 0.5 * o) * h, (j + 0.5 * o) * h, (k + 0.5 * o) * h};
          const double d = norm(x);
          if (d < r - gap && (hole == 0 || std::fabs(d - hole) > gap)) p.push_back(x);
        }
  return p;
}

std::vector<std::array<int, 2>> pairs(std::size_t n, int a, int b) {
  return std::vector<std::array<int, 2>>(n, {a, b});
}

int ball_label(const Vec3& x) { return norm(x) < 1 ? 1 : 0; }

ConformParams quiet() {
  ConformParams p;
  p.progress = false;
  return p;
}

std::string message(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

TEST(TetConform, BallKeepsItsBoundaryAndVolume) {
  const Mesh s = icosphere(3, 1.0);  // 642 vertices, 1280 triangles, edges ~0.1
  const double h = 0.1;
  std::vector<Vec3> inner = bcc_ball(1.0, h, 0.7 * h);
  const std::size_t lattice = inner.size();
  inner.push_back({2, 0, 0});                   // outside: dropped by label_at
  inner.push_back(s.vertices[5] * (1 - 1e-9));  // on top of a boundary vertex: dropped
  inner.push_back(inner[0]);                    // a duplicate: dropped
  ConformParams p = quiet();
  p.smooth_sweeps = 0;  // the interior points stay where they were given (TetSmooth tests the smoothing)
  const ConformResult r = conforming_tets(s, pairs(s.faces.size(), 0, 1), inner, ball_label, 0, p);
  EXPECT_EQ(r.interior_given, lattice + 3);
  EXPECT_EQ(r.interior_outside, 1u);
  EXPECT_EQ(r.interior_near_point, 2u);
  EXPECT_EQ(r.interior_kept, lattice);  // every lattice point is well inside
  EXPECT_EQ(r.interior_refused, 0u);
  EXPECT_EQ(r.regions, 1u);
  EXPECT_EQ(r.dropped_regions, 0u);
  EXPECT_EQ(r.split_vote_regions, 0u);
  const LabelledTets& t = r.mesh;
  // The boundary, exactly: the same vertices first, bit for bit, and the same triangles.
  ASSERT_GE(t.vertices.size(), s.vertices.size() + lattice);
  for (std::size_t i = 0; i < s.vertices.size(); ++i) {
    EXPECT_EQ(t.vertices[i].x, s.vertices[i].x);
    EXPECT_EQ(t.vertices[i].y, s.vertices[i].y);
    EXPECT_EQ(t.vertices[i].z, s.vertices[i].z);
  }
  for (std::size_t i = 0; i < lattice; ++i) EXPECT_EQ(norm(t.vertices[s.vertices.size() + i] - inner[i]), 0.0);
  EXPECT_EQ(t.triangles, s.faces);
  EXPECT_EQ(t.vertices.size(), s.vertices.size() + lattice + r.steiner_points);
  // Every step: positive tetrahedra, boundary faces = the triangles, volume of the polyhedron.
  ASSERT_EQ(r.steps.size(), 3u);
  EXPECT_EQ(r.steps[0].name, "cdt");
  EXPECT_EQ(r.steps[1].name, "refine");
  EXPECT_EQ(r.steps[2].name, "optimise");
  const double exact = enclosed_volume(s);  // 4/3 π minus the facets' cut-off caps
  for (const ConformStep& st : r.steps) {
    SCOPED_TRACE(st.name);
    EXPECT_EQ(st.quality.overall.non_positive, 0u);
    EXPECT_EQ(st.quality.triangles_missing, 0u);
    EXPECT_EQ(st.quality.triangles_extra, 0u);
    EXPECT_EQ(st.quality.boundary_faces, s.faces.size());
    EXPECT_EQ(st.quality.boundary_nonmanifold_edges, 0u);
    EXPECT_NEAR(st.quality.overall.volume, exact, 1e-9 * exact);
  }
  EXPECT_NEAR(tets_volume(t), exact, 1e-9 * exact);  // signed: all positive
  EXPECT_LT(exact, 4.0 / 3 * M_PI);
  EXPECT_GT(exact, 0.98 * 4.0 / 3 * M_PI);
  // The lattice next to the surface makes slivers; refinement and optimisation remove them.
  const TetStats& cdt = r.steps[0].quality.overall;
  const TetStats& fin = r.steps[2].quality.overall;
  EXPECT_LT(cdt.dihedral_min, 5.0);
  EXPECT_GE(fin.dihedral_min, 12.0);  // the bound (refinement aims at the default 18°; measured 17.5)
  EXPECT_LE(fin.dihedral_max, 160.0);
  EXPECT_GE(r.steps[2].share_25_140, 0.99);
  EXPECT_GT(r.steps[2].share_25_140, r.steps[0].share_25_140);
}

TEST(TetConform, NestedSpheresAreTwoMaterials) {
  const Mesh outer = icosphere(3, 1.0), inner = icosphere(2, 0.5);
  Mesh s = outer;
  const int off = int(s.vertices.size());
  s.vertices.insert(s.vertices.end(), inner.vertices.begin(), inner.vertices.end());
  for (auto f : inner.faces) s.faces.push_back({f[0] + off, f[1] + off, f[2] + off});
  auto labels = pairs(outer.faces.size(), 0, 1);
  const auto inner_pairs = pairs(inner.faces.size(), 1, 2);
  labels.insert(labels.end(), inner_pairs.begin(), inner_pairs.end());
  auto label = [](const Vec3& x) { return norm(x) < 0.5 ? 2 : norm(x) < 1 ? 1 : 0; };
  const ConformResult r = conforming_tets(s, labels, bcc_ball(1.0, 0.1, 0.07, 0.5), label, 0, quiet());
  EXPECT_EQ(r.regions, 2u);
  EXPECT_EQ(r.dropped_regions, 0u);
  const TetQuality& q = r.steps.back().quality;
  ASSERT_EQ(q.materials.size(), 2u);
  EXPECT_EQ(q.boundary_faces, outer.faces.size());
  EXPECT_EQ(q.interface_faces, inner.faces.size());
  EXPECT_EQ(q.triangles_missing + q.triangles_extra, 0u);
  EXPECT_EQ(r.mesh.triangles, s.faces);
  EXPECT_EQ(r.mesh.triangle_labels, labels);
  const double vi = enclosed_volume(inner), vo = enclosed_volume(outer);
  EXPECT_NEAR(tets_volume(r.mesh, 2), vi, 1e-9 * vi);
  EXPECT_NEAR(tets_volume(r.mesh, 1), vo - vi, 1e-9 * vo);
  EXPECT_EQ(q.overall.non_positive, 0u);
}

TEST(TetConform, CavityIsDropped) {
  // The inner sphere bounds a hole: both surfaces are (0, 1).
  const Mesh outer = icosphere(3, 1.0), inner = icosphere(2, 0.5);
  Mesh s = outer;
  const int off = int(s.vertices.size());
  s.vertices.insert(s.vertices.end(), inner.vertices.begin(), inner.vertices.end());
  for (auto f : inner.faces) s.faces.push_back({f[0] + off, f[1] + off, f[2] + off});
  auto label = [](const Vec3& x) { return norm(x) > 0.5 && norm(x) < 1 ? 1 : 0; };
  const ConformResult r =
      conforming_tets(s, pairs(s.faces.size(), 0, 1), bcc_ball(1.0, 0.1, 0.07, 0.5), label, 0, quiet());
  EXPECT_EQ(r.regions, 2u);
  EXPECT_EQ(r.dropped_regions, 1u);
  EXPECT_EQ(r.steps.back().quality.boundary_faces, s.faces.size());
  const double exact = enclosed_volume(outer) - enclosed_volume(inner);
  EXPECT_NEAR(tets_volume(r.mesh), exact, 1e-9 * exact);
}

// Two unit cubes stacked in z: lower material 1, upper 2, the middle square
// between them; 12 vertices, 22 triangles, all coplanar in pairs (TetGen must
// not merge and re-triangulate them).
struct Stack {
  Mesh m;
  std::vector<std::array<int, 2>> labels;
};
Stack two_cubes() {
  Stack s;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) s.m.vertices.push_back({double(i), double(j), double(k)});
  auto id = [](int i, int j, int k) { return i + 2 * j + 4 * k; };
  auto quad = [&](int a, int b, int c, int d, std::array<int, 2> l) {
    s.m.faces.push_back({a, b, c});
    s.m.faces.push_back({a, c, d});
    s.labels.push_back(l);
    s.labels.push_back(l);
  };
  for (int k = 0; k < 2; ++k) {
    const std::array<int, 2> l{0, k + 1};
    quad(id(0, 0, k), id(1, 0, k), id(1, 0, k + 1), id(0, 0, k + 1), l);  // y = 0
    quad(id(0, 1, k), id(0, 1, k + 1), id(1, 1, k + 1), id(1, 1, k), l);  // y = 1
    quad(id(0, 0, k), id(0, 0, k + 1), id(0, 1, k + 1), id(0, 1, k), l);  // x = 0
    quad(id(1, 0, k), id(1, 1, k), id(1, 1, k + 1), id(1, 0, k + 1), l);  // x = 1
  }
  quad(id(0, 0, 0), id(0, 1, 0), id(1, 1, 0), id(1, 0, 0), {0, 1});  // bottom
  quad(id(0, 0, 2), id(1, 0, 2), id(1, 1, 2), id(0, 1, 2), {0, 2});  // top
  quad(id(0, 0, 1), id(1, 0, 1), id(1, 1, 1), id(0, 1, 1), {1, 2});  // middle
  return s;
}

TEST(TetConform, StackedCubesKeepCoplanarTriangles) {
  const Stack s = two_cubes();
  auto label = [](const Vec3& x) {
    if (x.x < 0 || x.x > 1 || x.y < 0 || x.y > 1 || x.z < 0 || x.z > 2) return 0;
    return x.z < 1 ? 1 : 2;
  };
  // Two points on triangles (the interface, an outer face): TetGen would split
  // those triangles, so they are dropped.
  const std::vector<Vec3> inner = {{0.5, 0.5, 0.5}, {0.5, 0.5, 1.5}, {0.3, 0.6, 0.4}, {0.3, 0.6, 1.0},
                                   {0.4, 1e-9, 1.2}};
  ConformParams p = quiet();
  p.exude_rounds = 0;  // keep every point this test places
  const ConformResult r = conforming_tets(s.m, s.labels, inner, label, 0, p);
  EXPECT_EQ(r.interior_near_point, 2u);
  EXPECT_EQ(r.interior_kept, 3u);
  EXPECT_EQ(r.regions, 2u);
  EXPECT_EQ(r.mesh.triangles, s.m.faces);
  const TetQuality& q = r.steps.back().quality;
  EXPECT_EQ(q.interface_faces, 2u);
  EXPECT_EQ(q.boundary_faces, 20u);
  EXPECT_EQ(q.triangles_missing + q.triangles_extra, 0u);
  EXPECT_NEAR(tets_volume(r.mesh, 1), 1.0, 1e-12);
  EXPECT_NEAR(tets_volume(r.mesh, 2), 1.0, 1e-12);
}

TEST(TetConform, OddMaterialSurfaceIsRefused) {
  Stack s = two_cubes();
  s.labels[20] = s.labels[21] = {1, 3};  // the middle square no longer bounds material 2
  EXPECT_EQ(message([&] {
              conforming_tets(
                  s.m, s.labels, {}, [](const Vec3&) { return 1; }, 0, quiet());
            }),
            "conforming_tets: boundary: a material's surface is not closed: 8 edges (4 of material 2, 4 of "
            "material 3) are in an odd number of the triangles that have the material on one side; expected an "
            "even number");
}

TEST(TetConform, OpenSurfaceIsRefused) {
  Mesh s = icosphere(2, 1.0);
  s.faces.erase(s.faces.begin() + 7);    // a hole of 3 edges
  s.faces.erase(s.faces.begin() + 200);  // far away: 3 more
  EXPECT_EQ(message([&] { conforming_tets(s, pairs(s.faces.size(), 0, 1), {}, ball_label, 0, quiet(), "s.ply"); }),
            "conforming_tets: s.ply: not a closed surface: 6 edges in one triangle only, 0 in more than two; "
            "expected every edge in exactly 2 triangles");
  // With several materials an edge of one triangle is refused as well.
  auto labels = pairs(s.faces.size(), 0, 1);
  labels[0] = {0, 2};
  EXPECT_NE(message([&] {
              conforming_tets(s, labels, {}, ball_label, 0, quiet());
            }).find("not closed: 6 edges in one triangle only; expected every edge in at least 2 triangles"),
            std::string::npos);
}

TEST(TetConform, SelfIntersectingSurfaceIsRefused) {
  // Two overlapping spheres as one closed surface: every edge in 2 triangles, but they cross.
  const Mesh a = icosphere(2, 1.0), b = icosphere(2, 1.0, {0.7, 0.1, 0.05});
  Mesh s = a;
  const int off = int(s.vertices.size());
  s.vertices.insert(s.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (auto f : b.faces) s.faces.push_back({f[0] + off, f[1] + off, f[2] + off});
  const int crossing = count_self_intersections(s);
  ASSERT_GT(crossing, 0);
  const std::string m = message([&] {
    conforming_tets(
        s, pairs(s.faces.size(), 0, 1), {}, [](const Vec3&) { return 1; }, 0, quiet());
  });
  EXPECT_NE(m.find("self-intersecting: " + std::to_string(crossing) + " pairs of triangles cross"), std::string::npos)
      << m;
}

TEST(TetConform, BadInputAndParameters) {
  const Mesh s = icosphere(1, 1.0);
  EXPECT_NE(message([&] {
              conforming_tets(s, pairs(3, 0, 1), {}, ball_label, 0, quiet());
            }).find("3 label pairs for 80 triangles"),
            std::string::npos);
  EXPECT_NE(message([&] {
              conforming_tets(s, pairs(s.faces.size(), 1, 1), {}, ball_label, 0, quiet());
            }).find("80 triangles have labels (a, b) with a >= b"),
            std::string::npos);
  Mesh dup = s;
  dup.vertices.push_back(dup.vertices[3]);
  dup.faces[0][0] = int(dup.vertices.size()) - 1;
  EXPECT_NE(message([&] {
              conforming_tets(dup, pairs(s.faces.size(), 0, 1), {}, ball_label, 0, quiet());
            }).find("1 vertices repeat the position of another vertex"),
            std::string::npos);
  // Everything outside by label_at: nothing to mesh.
  EXPECT_NE(message([&] {
              conforming_tets(
                  s, pairs(s.faces.size(), 0, 1), {}, [](const Vec3&) { return 0; }, 0, quiet());
            }).find("every region (1) is outside (label 0)"),
            std::string::npos);
  ConformParams p = quiet();
  p.min_dihedral = 70;
  EXPECT_THROW(conforming_tets(s, pairs(s.faces.size(), 0, 1), {}, ball_label, 0, p), UsageError);
  p = quiet();
  p.max_dihedral = 80;
  EXPECT_THROW(conforming_tets(s, pairs(s.faces.size(), 0, 1), {}, ball_label, 0, p), UsageError);
}

TEST(TetConform, StepsCanBeSwitchedOff) {
  const Mesh s = icosphere(2, 1.0);
  ConformParams p = quiet();
  p.min_dihedral = 0;
  p.optimise = false;
  p.exude_rounds = 0;
  p.smooth_sweeps = 0;
  const ConformResult r = conforming_tets(s, pairs(s.faces.size(), 0, 1), bcc_ball(1, 0.2, 0.14), ball_label, 0, p);
  ASSERT_EQ(r.steps.size(), 1u);
  EXPECT_EQ(r.steps[0].name, "cdt");
  EXPECT_EQ(r.steiner_points, 0u);  // a plain constrained Delaunay of a convex polyhedron needs none
  const double exact = enclosed_volume(s);
  EXPECT_NEAR(tets_volume(r.mesh), exact, 1e-9 * exact);
}

}  // namespace
}  // namespace pm

namespace pm {
namespace {

TEST(TetConform, InteriorPointsOfSliversAreRemovedAndMeshedAgain) {
  // An interior point 1e-3 inside a boundary triangle's centroid makes a flat
  // tetrahedron on that triangle (the boundary cannot change). Removing the
  // interior points of tetrahedra outside [12, 160] degrees and meshing
  // again takes it away.
  const Mesh s = icosphere(2, 1.0);
  const auto& f = s.faces[0];
  const Vec3 c = (s.vertices[std::size_t(f[0])] + s.vertices[std::size_t(f[1])] + s.vertices[std::size_t(f[2])]) / 3.0;
  std::vector<Vec3> inner = bcc_ball(1, 0.2, 0.14);
  inner.push_back(c * (1 - 1e-3 / norm(c)));
  ConformParams p = quiet();
  p.min_dihedral = 0;
  p.optimise = false;
  p.exude_rounds = 0;
  p.smooth_sweeps = 0;         // smoothing would move the point off the triangle too
  p.boundary_clearance = 0;    // which would drop the point before meshing (next test)
  const ConformResult kept = conforming_tets(s, pairs(s.faces.size(), 0, 1), inner, ball_label, 0, p);
  ASSERT_LT(kept.steps.back().quality.overall.dihedral_min, 12.0);
  p.exude_rounds = 2;
  const ConformResult r = conforming_tets(s, pairs(s.faces.size(), 0, 1), inner, ball_label, 0, p);
  EXPECT_GE(r.interior_exuded, 1u);
  ASSERT_GE(r.steps.size(), 2u);
  EXPECT_EQ(r.steps[1].name, "cdt 2");
  for (const Vec3& v : r.mesh.vertices) EXPECT_GT(norm(v - inner.back()), 1e-12);
  EXPECT_GT(r.steps.back().quality.overall.dihedral_min, kept.steps.back().quality.overall.dihedral_min);
  EXPECT_EQ(r.mesh.triangles, s.faces);  // the boundary is untouched
}

TEST(TetConform, BadTetrahedraGiveUpTheirInteriorPointsOrTheirNeighbours) {
  // Vertices 0-3: boundary, 4-6: interior points [4, 7), 7: a Steiner point.
  // Tet A = (0,1,2,3) is flat (3 lies almost in the plane of 0,1,2) and has
  // no interior vertex; tet B = (0,1,2,4) shares its face and holds point 4;
  // tet C = (5,6,7,4) is regular and far from A but touches B at 4.
  LabelledTets m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 0.01}, {0.3, 0.3, -0.8},
                {5, 5, 5}, {6, 5, 5}, {5, 6, 5}};
  m.vertices.push_back({5.33, 5.33, 5.8});  // 8: makes C regular-ish with 5, 6, 7
  m.tets = {{0, 1, 2, 3}, {0, 2, 1, 4}, {5, 6, 7, 8}};
  m.materials = {1, 1, 1};
  std::vector<std::size_t> rm;
  // A alone is outside [12, 160]: no interior vertex of its own, so the points of the tetrahedra at its
  // vertices go (4, from B); C's are kept.
  EXPECT_EQ(tets_outside_band(m, 4, 7, 12, 160, &rm), 1u);
  EXPECT_EQ(rm, (std::vector<std::size_t>{4}));
  EXPECT_EQ(tets_outside_band(m, 4, 7, 12, 160), 1u);
  // A bad tetrahedron with an interior vertex gives up only its own: flatten C by moving 8 into the plane.
  m.vertices[8] = {5.33, 5.33, 5.01};
  m.tets[2] = {5, 6, 7, 8};
  EXPECT_EQ(tets_outside_band(m, 4, 9, 12, 160, &rm), 2u);
  EXPECT_EQ(rm, (std::vector<std::size_t>{4, 5, 6, 7, 8}));  // A's ring (4) and C's own (5-8, all in [4, 9))
  EXPECT_EQ(tets_outside_band(m, 0, 0, 0, 180, &rm), 0u);
  EXPECT_TRUE(rm.empty());
}

TEST(TetConform, PointsTooCloseToTheBoundaryAreDroppedBeforeMeshing) {
  // The same point 1e-3 above a triangle (edges ~0.3) and one 0.05 above
  // another: both within 0.2 of the longest edge, so both go before the
  // first meshing, which then has no flat tetrahedron on them; points
  // farther than that stay.
  const Mesh s = icosphere(2, 1.0);
  auto above = [&](std::size_t t, double height) {
    const auto& f = s.faces[t];
    const Vec3 c = (s.vertices[std::size_t(f[0])] + s.vertices[std::size_t(f[1])] + s.vertices[std::size_t(f[2])]) / 3.0;
    return c * (1 - height / norm(c));
  };
  double longest = 0;
  for (const auto& f : s.faces)
    for (int k = 0; k < 3; ++k)
      longest = std::max(longest, norm(s.vertices[std::size_t(f[(k + 1) % 3])] - s.vertices[std::size_t(f[k])]));
  std::vector<Vec3> inner = bcc_ball(1, 0.2, 0.14);
  const std::size_t lattice = inner.size();
  inner.push_back(above(0, 1e-3));
  inner.push_back(above(40, 0.05));
  ConformParams p = quiet();
  p.min_dihedral = 0;
  p.optimise = false;
  p.exude_rounds = 0;
  p.smooth_sweeps = 0;
  ASSERT_LT(0.05, 0.2 * longest);
  ASSERT_LT(0.2 * longest, 0.14);  // the lattice keeps more than the clearance
  const ConformResult r = conforming_tets(s, pairs(s.faces.size(), 0, 1), inner, ball_label, 0, p);
  EXPECT_EQ(r.interior_near_boundary, 2u);
  EXPECT_EQ(r.interior_kept, lattice);
  EXPECT_EQ(r.interior_exuded, 0u);
  p.boundary_clearance = 0;
  const ConformResult all = conforming_tets(s, pairs(s.faces.size(), 0, 1), inner, ball_label, 0, p);
  EXPECT_EQ(all.interior_near_boundary, 0u);
  EXPECT_EQ(all.interior_kept, lattice + 2);
  EXPECT_LT(all.steps.back().quality.overall.dihedral_min, 5.0);
  EXPECT_GT(r.steps.back().quality.overall.dihedral_min, all.steps.back().quality.overall.dihedral_min);
  p.boundary_clearance = 1;
  EXPECT_THROW(conforming_tets(s, pairs(s.faces.size(), 0, 1), inner, ball_label, 0, p), UsageError);
}

}  // namespace
}  // namespace pm

#include "pm/mesh/tet_smooth.h"

#include <tbb/global_control.h>

namespace pm {
namespace {

TEST(TetSmooth, OdtRaisesMeanQualityKeepsWorstBoundaryAndVolume) {
  // A jittered lattice inside an icosphere, meshed without TetGen's own
  // optimisation: ODT smoothing must raise the mean radius ratio, never
  // lower the smallest one (each move keeps the worst around its vertex),
  // keep every tetrahedron positive, the boundary vertices where they are and
  // the enclosed volume exact (the boundary does not move).
  const Mesh s = icosphere(3, 1.0);
  std::vector<Vec3> inner = bcc_ball(1, 0.18, 0.1);
  std::uint64_t state = 7;
  for (Vec3& x : inner) {
    auto u = [&] {
      state = state * 6364136223846793005ULL + 1442695040888963407ULL;
      return double(state >> 11) / double(1ULL << 53) - 0.5;
    };
    x += Vec3(u(), u(), u()) * 0.1;
  }
  ConformParams p = quiet();
  p.min_dihedral = 0;
  p.optimise = false;
  p.exude_rounds = 0;
  p.smooth_sweeps = 0;
  const ConformResult r = conforming_tets(s, pairs(s.faces.size(), 0, 1), inner, ball_label, 0, p);
  LabelledTets t = r.mesh;
  const TetQuality before = tet_quality(t);
  const TetSmoothResult sr = odt_smooth(t, s.vertices.size());
  const TetQuality after = tet_quality(t);
  EXPECT_GT(sr.moves, 0u);
  EXPECT_GT(after.overall.rr_mean, before.overall.rr_mean + 0.002);  // +0.005 measured
  // ODT moves keep the worst radius ratio around each vertex, perturbation
  // keeps it above min(old, 0.25); perturbation raises the worst angle
  // margin min(smallest / 15°, (180° - largest) / 25°) around what it moves,
  // and the ODT moves keep angles within their old extremes or [25°, 140°].
  EXPECT_GE(after.overall.rr_min, std::min(before.overall.rr_min, 0.25));
  auto worst_margin = [](const LabelledTets& m) {
    double w = 1e300;
    for (const auto& c : m.tets) {
      const auto d = tet_dihedrals(m.vertices[std::size_t(c[0])], m.vertices[std::size_t(c[1])],
                                   m.vertices[std::size_t(c[2])], m.vertices[std::size_t(c[3])]);
      const auto [lo, hi] = std::minmax_element(d.begin(), d.end());
      w = std::min(w, std::min(*lo / 15, (180 - *hi) / 25));
    }
    return w;
  };
  EXPECT_GE(worst_margin(t), worst_margin(r.mesh));
  EXPECT_GT(after.overall.dihedral_min, before.overall.dihedral_min);
  EXPECT_EQ(after.overall.non_positive, 0u);
  for (std::size_t i = 0; i < s.vertices.size(); ++i) EXPECT_EQ(t.vertices[i], r.mesh.vertices[i]);
  EXPECT_NEAR(after.overall.volume, before.overall.volume, 1e-9 * before.overall.volume);
  EXPECT_EQ(t.tets, r.mesh.tets);  // connectivity kept
  EXPECT_THROW(odt_smooth(t, t.vertices.size() + 1), UsageError);
  TetSmoothParams bad;
  bad.sweeps = 0;
  EXPECT_THROW(odt_smooth(t, 0, bad), UsageError);
}

TEST(TetSmooth, SameMeshForAnyThreadCount) {
  // The colours move one after the other, each in parallel: 1 and 4
  // threads give the same vertices, bit for bit.
  const Mesh s = icosphere(3, 1.0);
  std::vector<Vec3> inner = bcc_ball(1, 0.12, 0.07);
  ConformParams p = quiet();
  p.exude_rounds = 0;
  p.smooth_sweeps = 0;
  const ConformResult r = conforming_tets(s, pairs(s.faces.size(), 0, 1), inner, ball_label, 0, p);
  LabelledTets one = r.mesh, four = r.mesh;
  TetSmoothResult a, b;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    a = odt_smooth(one, s.vertices.size());
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 4);
    b = odt_smooth(four, s.vertices.size());
  }
  ASSERT_GT(a.moves, 1000u);
  EXPECT_EQ(a.moves, b.moves);
  EXPECT_EQ(a.perturbed, b.perturbed);
  EXPECT_EQ(one.vertices, four.vertices);
  EXPECT_NE(one.vertices, r.mesh.vertices);
}

}  // namespace
}  // namespace pm
