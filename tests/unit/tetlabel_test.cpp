#include "pm/mesh/tetlabel.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "pm/base/error.h"

namespace pm {
namespace {

std::vector<Vec3> fibonacci_sphere(int n, double R) {
  std::vector<Vec3> p;
  const double ga = M_PI * (3 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1 - 2 * (i + 0.5) / n, r = std::sqrt(1 - z * z);
    p.push_back(Vec3(r * std::cos(ga * i), r * std::sin(ga * i), z) * R);
  }
  return p;
}

double torus_F(const Vec3& x, double R, double r) {
  const double q = std::sqrt(x.x * x.x + x.y * x.y) - R;
  return std::sqrt(q * q + x.z * x.z) - r;
}

// Enclosed volume by the divergence theorem; positive iff faces point outward.
double enclosed_volume(const Mesh& m) {
  double v = 0;
  for (const auto& f : m.faces) v += dot(m.vertices[f[0]], cross(m.vertices[f[1]], m.vertices[f[2]])) / 6.0;
  return v;
}

TEST(TetLabel, FibonacciSphereGivesClosedGenusZero) {
  const auto pts = fibonacci_sphere(2000, 1.0);
  TetMesh tm = delaunay(pts);
  label_tets(tm, [](const Vec3& x) { return norm(x) < 1.0 ? 1 : 0; });
  const Mesh s = material_surface(tm, 1, 0);
  const MeshTopology t = mesh_topology(s);
  EXPECT_TRUE(t.closed_manifold()) << t.boundary_edges << " boundary, " << t.nonmanifold_edges << " nm edges";
  EXPECT_EQ(t.vertices, 2000u);
  EXPECT_EQ(t.faces, 3996u);  // 2V - 4 for a closed genus-0 triangulation
  EXPECT_EQ(t.genus, 0);
  EXPECT_EQ(t.components, 1u);
  // Outward orientation: volume positive and close to the inscribed polyhedron's (< 4π/3).
  const double vol = enclosed_volume(s);
  EXPECT_GT(vol, 0.99 * 4.0 / 3.0 * M_PI);
  EXPECT_LT(vol, 4.0 / 3.0 * M_PI);
}

// A half ball whose flat face z = 0 is sampled by an exact hexagonal grid:
// those points are coplanar and on the convex hull (a mask cut by the volume
// border gives the same). Enclosed by far box corners, the flat face is a
// proper Delaunay triangulation of its hexagonal grid; as a hull facet, TetGen
// joins its points by slivers.
TEST(TetLabel, EnclosedDelaunayMeshesAFlatHullFace) {
  const double s = 0.1;
  std::vector<Vec3> pts;
  for (const Vec3& x : fibonacci_sphere(2400, 1.0))
    if (x.z < -0.5 * s) pts.push_back(x);
  for (int j = -12; j <= 12; ++j)
    for (int i = -12; i <= 12; ++i) {
      const Vec3 x{(i + 0.5 * (j & 1)) * s, j * s * std::sqrt(3.0) / 2, 0.0};
      if (norm(x) < 1 - 0.5 * s) pts.push_back(x);
    }
  auto inside = [](const Vec3& x) { return x.z < 0 && norm(x) < 1.0 ? 1 : 0; };
  auto flat_face_rr_min = [&](TetMesh tm) {
    label_tets(tm, inside);
    const Mesh m = material_surface(tm, 1, 0);
    if (!mesh_topology(m).closed_manifold()) return -1.0;  // worse than any triangle
    double worst = 1;
    for (const auto& f : m.faces) {
      const Vec3 &a = m.vertices[f[0]], &b = m.vertices[f[1]], &c = m.vertices[f[2]];
      if (a.z == 0 && b.z == 0 && c.z == 0) {
        const double la = norm(b - c), lb = norm(c - a), lc = norm(a - b), p = (la + lb + lc) / 2;
        const double area = std::sqrt(std::max(0.0, p * (p - la) * (p - lb) * (p - lc)));
        worst = std::min(worst, area > 0 ? 2 * (area / p) / (la * lb * lc / (4 * area)) : 0.0);
      }
    }
    return worst;
  };
  // Inside the disc the grid triangles are equilateral; at its rim they meet
  // the sphere's points, so allow the rim's irregular triangles.
  EXPECT_GT(flat_face_rr_min(delaunay_enclosed(pts)), 0.3);  // closed manifold, no slivers
  EXPECT_LT(flat_face_rr_min(delaunay(pts)), 0.3);  // what the enclosure fixes (slivers or not closed)
}

TEST(TetLabel, RegularTorusGridIsRobustToCosphericalPoints) {
  // SPEC §6: 2,924 points on an exactly regular torus grid broke naive labelling.
  // Exactly regular (jitter 0) and nearly regular grids must all come out right.
  const double R = 1.0, r = 0.4;
  for (double jitter : {0.0, 1e-9, 1e-6, 2e-3}) {
  SCOPED_TRACE("jitter " + std::to_string(jitter));
  std::vector<Vec3> pts;
  const int nu = 68, nv = 43;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const double u = 2 * M_PI * i / nu, v = 2 * M_PI * j / nv;
      pts.emplace_back((R + r * std::cos(v)) * std::cos(u) + jitter * U(rng),
                       (R + r * std::cos(v)) * std::sin(u) + jitter * U(rng), r * std::sin(v) + jitter * U(rng));
    }
  ASSERT_EQ(pts.size(), 2924u);
  TetMesh tm = delaunay(pts);
  const TetLabelStats st = label_tets(tm, [&](const Vec3& x) { return torus_F(x, R, r) < 0 ? 1 : 0; });
  if (jitter == 0) EXPECT_GT(st.flat, 1000u);  // the exact grid makes many degenerate tetrahedra
  const Mesh s = material_surface(tm, 1, 0);
  const MeshTopology t = mesh_topology(s);
  EXPECT_TRUE(t.closed_manifold()) << t.boundary_edges << " boundary, " << t.nonmanifold_edges << " nm edges, "
                                   << t.nonmanifold_vertices << " nm vertices";
  EXPECT_EQ(t.euler, 0);
  EXPECT_EQ(t.genus, 1);
  EXPECT_EQ(t.vertices, 2924u);
  EXPECT_EQ(t.faces, 2 * 2924u);
  EXPECT_GT(enclosed_volume(s), 0);
  }
}

TEST(TetLabel, InterfaceOfTwoMaterialsIsSharedExactly) {
  // Points on two touching spheres' surfaces and their shared disc: labels 1 (x<0), 2 (x>0), 0 outside.
  auto pts = fibonacci_sphere(1500, 1.0);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int i = 0; i < 300; ++i) {
    const double y = U(rng), z = U(rng);
    if (y * y + z * z < 0.95) pts.emplace_back(0.0, y, z);
  }
  TetMesh tm = delaunay(pts);
  label_tets(tm, [](const Vec3& x) { return norm(x) >= 1.0 ? 0 : (x.x < 0 ? 1 : 2); });
  const Mesh all = interface_mesh(tm, 0);
  const Mesh m1 = material_surface(tm, 1, 0), m2 = material_surface(tm, 2, 0);
  const MeshTopology t1 = mesh_topology(m1), t2 = mesh_topology(m2);
  EXPECT_TRUE(t1.closed_manifold());
  EXPECT_TRUE(t2.closed_manifold());
  EXPECT_EQ(t1.genus, 0);
  EXPECT_EQ(t2.genus, 0);
  // Interface faces: each material surface face appears once; the shared 1|2 faces appear in both.
  std::size_t shared = 0, a0 = 0;
  const auto& la = all.face_ints.at("label_a");
  const auto& lb = all.face_ints.at("label_b");
  for (std::size_t i = 0; i < la.size(); ++i) {
    EXPECT_LT(la[i], lb[i]);
    shared += la[i] == 1 && lb[i] == 2;
    a0 += la[i] == 0;
  }
  EXPECT_GT(shared, 50u);
  EXPECT_EQ(m1.faces.size() + m2.faces.size(), a0 + 2 * shared);
  // Water-tight non-manifold interface: no boundary edges.
  EXPECT_EQ(mesh_topology(all).boundary_edges, 0u);
  EXPECT_GT(mesh_topology(all).nonmanifold_edges, 0u);  // the junction curve
}

// The parallel (CGAL) and TetGen tetrahedralisations of points in general
// position are the same Delaunay tetrahedra; the parallel one comes in a
// canonical order with positive orientation, neighbour i sharing the face
// opposite corner i, and its tetrahedra fill the hull (volumes add up).
TEST(TetLabel, ParallelDelaunayMatchesTetGen) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vec3> pts(3000);
  for (Vec3& p : pts) p = {u(rng), u(rng), 0.5 * u(rng)};
  const TetMesh a = delaunay(pts), b = tetgen_delaunay(pts);
  auto sorted_set = [](const TetMesh& m) {
    std::vector<std::array<int, 4>> s = m.tets;
    for (auto& t : s) std::sort(t.begin(), t.end());
    std::sort(s.begin(), s.end());
    return s;
  };
  EXPECT_EQ(sorted_set(a), sorted_set(b));
  const auto sa = sorted_set(a);
  std::vector<std::array<int, 4>> in_order = a.tets;
  for (auto& t : in_order) std::sort(t.begin(), t.end());
  EXPECT_EQ(in_order, sa);  // canonical order
  double vol = 0;
  for (std::size_t t = 0; t < a.tets.size(); ++t) {
    const auto& v = a.tets[t];
    const Vec3 &p = a.points[v[0]], &q = a.points[v[1]], &r = a.points[v[2]], &w = a.points[v[3]];
    const double v6 = dot(q - p, cross(r - p, w - p));
    EXPECT_GT(v6, 0);
    vol += v6 / 6;
    for (int i = 0; i < 4; ++i) {
      const int n = a.neighbours[t][std::size_t(i)];
      if (n < 0) continue;
      int shared = 0;
      for (int k = 0; k < 4; ++k)
        if (k != i) shared += int(std::count(a.tets[std::size_t(n)].begin(), a.tets[std::size_t(n)].end(), v[k]));
      EXPECT_EQ(shared, 3) << "tet " << t << " neighbour " << i;
      EXPECT_EQ(std::count(a.tets[std::size_t(n)].begin(), a.tets[std::size_t(n)].end(), v[i]), 0);
    }
  }
  double vol_b = 0;
  for (const auto& v : b.tets)
    vol_b += dot(b.points[v[1]] - b.points[v[0]], cross(b.points[v[2]] - b.points[v[0]], b.points[v[3]] - b.points[v[0]])) / 6;
  EXPECT_NEAR(vol, vol_b, 1e-9 * vol_b);
}

TEST(TetLabel, BadInput) {
  EXPECT_THROW(delaunay({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}), InputError);
  EXPECT_THROW(delaunay({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 1}}), InputError);  // a duplicate
  EXPECT_THROW(delaunay({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {2, 3, 0}}), InputError);  // coplanar
  EXPECT_THROW(delaunay({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, NAN}}), InputError);
}

}  // namespace
}  // namespace pm

namespace pm {
namespace {

TEST(TetLabel, MakeManifoldOpensPinches) {
  // Two unit spheres touching at the origin, sampled with the touching point:
  // the union's surface is pinched there.
  std::vector<Vec3> pts;
  for (const Vec3& p : fibonacci_sphere(800, 1.0)) {
    pts.push_back(p + Vec3(1, 0, 0));
    pts.push_back(p - Vec3(1, 0, 0));
  }
  pts.emplace_back(0, 0, 0);
  TetMesh tm = delaunay(pts);
  label_tets(tm, [](const Vec3& x) {
    return std::min(norm(x - Vec3(1, 0, 0)), norm(x + Vec3(1, 0, 0))) < 1.0 ? 1 : 0;
  });
  const MeshTopology before = mesh_topology(material_surface(tm, 1, 0));
  EXPECT_FALSE(before.closed_manifold());
  const std::size_t flips = make_manifold(tm, 1, 0);
  EXPECT_GT(flips, 0u);
  const MeshTopology after = mesh_topology(material_surface(tm, 1, 0));
  EXPECT_TRUE(after.closed_manifold()) << after.nonmanifold_edges << " nm edges, " << after.nonmanifold_vertices
                                       << " nm vertices";
  // Only the contact point and its first ring (about 6 particles) may be buried.
  EXPECT_GE(after.vertices + 10, before.vertices);
}

}  // namespace
}  // namespace pm
