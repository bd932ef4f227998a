#include "pm/mesh/tetlabel_materials.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <memory>
#include <set>

#include "pm/base/error.h"
#include "pm/mesh/meshstats_materials.h"
#include "pm/mesh/tet_quality.h"
#include "pm/mesh/surface_improve.h"

namespace pm {
namespace {

// Analytic distance-like field given by a function (negative inside).
class FnField : public ScalarField {
 public:
  explicit FnField(std::function<double(const Vec3&)> f) : f_(std::move(f)) {}
  double value(const Vec3& x) const override { return f_(x); }
  double value_gradient(const Vec3& x, Vec3& g) const override {
    const double e = 1e-6;
    for (int a = 0; a < 3; ++a) {
      Vec3 p = x, q = x;
      p[a] += e;
      q[a] -= e;
      g[a] = (f_(p) - f_(q)) / (2 * e);
    }
    return f_(x);
  }
  double evaluate(const Vec3& x, Vec3& g, Mat3& h) const override {
    h = Mat3();
    return value_gradient(x, g);
  }
  Box domain() const override { return Box{{-2, -2, -2}, {2, 2, 2}}; }
  double resolution() const override { return 0.05; }
  std::string describe() const override { return "fn"; }

 private:
  std::function<double(const Vec3&)> f_;
};

// Background 1 around a unit ball split by the plane x = 0 into material 2
// (x < 0) and 3 (x > 0): two 2-junction surfaces per half, one triple circle.
MaterialSet split_ball() {
  MaterialSet ms;
  auto ball = [](const Vec3& p) { return norm(p) - 1.0; };
  ms.labels = {1, 2, 3};
  ms.fields.push_back(std::make_shared<FnField>([=](const Vec3& p) { return -ball(p); }));
  ms.fields.push_back(std::make_shared<FnField>([=](const Vec3& p) { return std::max(ball(p), p.x); }));
  ms.fields.push_back(std::make_shared<FnField>([=](const Vec3& p) { return std::max(ball(p), -p.x); }));
  return ms;
}

// Particles on the interfaces, spacing about s: the triple circle, the sphere
// away from it, and the disk x = 0 inside it (hexagonal grid).
std::vector<Vec3> split_ball_points(double s) {
  std::vector<Vec3> pts;
  const double pi = std::acos(-1.0);
  const int nc = int(std::round(2 * pi / s));
  for (int i = 0; i < nc; ++i) pts.push_back({0, std::cos(2 * pi * i / nc), std::sin(2 * pi * i / nc)});
  const int ns = int(std::round(4 * pi / (s * s * std::sqrt(3.0) / 2)));
  const double golden = pi * (3 - std::sqrt(5.0));
  for (int i = 0; i < ns; ++i) {
    const double x = 1 - 2 * (i + 0.5) / ns, r = std::sqrt(1 - x * x), t = golden * i;
    if (std::fabs(x) < 0.5 * s) continue;
    pts.push_back({x, r * std::cos(t), r * std::sin(t)});
  }
  for (int j = -20; j <= 20; ++j)
    for (int i = -20; i <= 20; ++i) {
      const double y = s * (i + 0.5 * (j & 1)), z = s * j * std::sqrt(3.0) / 2;
      if (std::hypot(y, z) < 1 - 0.6 * s) pts.push_back({0, y, z});
    }
  return pts;
}

TEST(TetLabelMaterials, SplitBallIsWatertightAndShared) {
  const MaterialSet ms = split_ball();
  EXPECT_EQ(auto_outside_label(ms), 1);
  TetMesh tm = delaunay(split_ball_points(0.15));
  MaterialMeshParams p;
  p.outside_label = 1;
  const MaterialMeshes mm = mesh_materials(tm, ms, p);
  EXPECT_EQ(mm.pairs, (std::vector<std::pair<int, int>>{{1, 2}, {1, 3}, {2, 3}}));
  ASSERT_EQ(mm.surfaces.size(), 2u);  // 2 and 3 (1 is outside)
  EXPECT_TRUE(mm.nonmanifold_materials.empty());
  for (const auto& [l, m] : mm.surfaces) {
    const MeshTopology t = mesh_topology(m);
    EXPECT_TRUE(t.closed_manifold()) << "material " << l << ": " << t.boundary_edges << " boundary, "
                                     << t.nonmanifold_edges << " non-manifold edges";
    EXPECT_EQ(t.components, 1u);
    EXPECT_EQ(t.genus, 0);
  }
  // Shared triangles: every (2,3) interface face is in both material
  // surfaces with opposite orientation, so F2 + F3 = F(1,2) + F(1,3) + 2 F(2,3).
  const auto& a = mm.interfaces.face_ints.at("label_a");
  const auto& b = mm.interfaces.face_ints.at("label_b");
  std::size_t f12 = 0, f13 = 0, f23 = 0;
  for (std::size_t f = 0; f < a.size(); ++f) {
    ASSERT_LT(a[f], b[f]);
    if (a[f] == 1 && b[f] == 2) ++f12;
    if (a[f] == 1 && b[f] == 3) ++f13;
    if (a[f] == 2 && b[f] == 3) ++f23;
  }
  EXPECT_GT(f23, 50u);
  EXPECT_EQ(mm.surfaces.at(2).faces.size(), f12 + f23);
  EXPECT_EQ(mm.surfaces.at(3).faces.size(), f13 + f23);
  // The interface mesh passes every multi-material check.
  const InterfaceQuality q = interface_quality(mm.interfaces);
  EXPECT_EQ(q.boundary_edges, 0u);
  EXPECT_EQ(q.bad_edges, 0u);
  EXPECT_EQ(q.self_faces, 0u);
  EXPECT_GT(q.junction_edges, 20u);  // the triple circle, about 2 pi / 0.15 = 42 edges
  EXPECT_LT(q.junction_edges, 80u);
  ASSERT_EQ(q.materials.size(), 3u);
  for (const auto& [l, mq] : q.materials) {
    EXPECT_TRUE(mq.topology.closed_manifold()) << "material " << l;
    EXPECT_EQ(mq.self_intersecting_pairs, 0) << "material " << l;
  }
  EXPECT_TRUE(check_interface_requirements(q, "watertight,manifold,labels_consistent,no_self_intersections").empty());
  // Material 1's surface is the whole sphere: its faces are exactly (1,2) and (1,3).
  EXPECT_EQ(q.materials.at(1).faces, f12 + f13);
}

// improve_interfaces on the split ball: the triple circle's vertices stay on
// the circle (they slide along it), every other vertex stays on its interface (|d_a - d_b| tiny), quality rises,
// and every multi-material check still passes on the improved mesh and on the
// material surfaces rebuilt from it.
TEST(TetLabelMaterials, ImprovedInterfacesKeepJunctionsAndChecks) {
  const MaterialSet ms = split_ball();
  // Jittered points: a poorer start than the regular grids.
  std::vector<Vec3> pts = split_ball_points(0.15);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double j = 0.02 * std::sin(12.9898 * double(i)), k = 0.02 * std::cos(78.233 * double(i));
    Vec3& x = pts[i];
    if (std::fabs(x.x) < 1e-12 && norm(x) > 0.99) {  // along the triple circle, staying on it
      const double a = std::atan2(x.z, x.y) + 2 * j;
      x = {0, std::cos(a), std::sin(a)};
      continue;
    }
    if (std::fabs(x.x) < 1e-12) x = x + Vec3{0, j, k};       // slide inside the disk x = 0
    else x = normalized(x + Vec3{0, j, k});                  // slide on the sphere
  }
  TetMesh tm = delaunay(pts);
  MaterialMeshParams p;
  p.outside_label = 1;
  MaterialMeshes mm = mesh_materials(tm, ms, p);
  const Mesh before = mm.interfaces;
  const InterfaceQuality q0 = interface_quality(before);
  const SurfaceImproveStats st = improve_interfaces(mm.interfaces, ms);
  const Mesh& after = mm.interfaces;
  ASSERT_EQ(after.vertices.size(), before.vertices.size());
  EXPECT_GT(st.moves, 0u);
  EXPECT_GT(st.rr_mean_after, st.rr_mean_before);
  EXPECT_GE(st.rr_min_after, std::min(st.rr_min_before, 0.5));
  const auto& la = after.face_ints.at("label_a");
  const auto& lb = after.face_ints.at("label_b");
  for (std::size_t f = 0; f < after.faces.size(); ++f)
    for (int v : after.faces[f]) {
      const Vec3& x = after.vertices[std::size_t(v)];
      const Vec3& x0 = before.vertices[std::size_t(v)];
      if (std::fabs(x0.x) < 1e-12 && norm(x0) > 0.99) {
        // Triple-circle vertices slide along the circle and stay on it.
        ASSERT_LE(std::fabs(x.x), 1e-5) << "a triple-circle vertex left the plane x = 0";
        ASSERT_NEAR(norm(x), 1.0, 1e-5) << "a triple-circle vertex left the sphere";
        continue;
      }
      Vec3 g;
      const double da = ms.fields[ms.index_of(la[f])]->value_gradient(x, g);
      const double db = ms.fields[ms.index_of(lb[f])]->value_gradient(x, g);
      // Vertices on several interfaces are fixed and were on both already.
      ASSERT_LE(std::fabs(da - db), 1e-5) << "vertex " << v << " left interface " << la[f] << "|" << lb[f];
    }
  const InterfaceQuality q1 = interface_quality(after);
  EXPECT_EQ(q1.boundary_edges, 0u);
  EXPECT_EQ(q1.bad_edges, 0u);
  EXPECT_EQ(q1.self_faces, 0u);
  EXPECT_EQ(q1.junction_edges, q0.junction_edges);
  for (const auto& [l, mq] : q1.materials) {
    EXPECT_TRUE(mq.topology.closed_manifold()) << "material " << l;
    EXPECT_EQ(mq.self_intersecting_pairs, 0) << "material " << l;
    EXPECT_GT(mq.rr_mean, q0.materials.at(l).rr_mean) << "material " << l;
  }
  for (int l : {2, 3}) {
    const Mesh m = material_from_interfaces(after, l);
    const MeshTopology t = mesh_topology(m);
    EXPECT_TRUE(t.closed_manifold()) << "material " << l;
    EXPECT_EQ(t.genus, 0);
    EXPECT_EQ(m.faces.size(), mm.surfaces.at(l).faces.size());
  }
}

TEST(TetLabelMaterials, InterfaceChecksFail) {
  const MaterialSet ms = split_ball();
  TetMesh tm = delaunay(split_ball_points(0.2));
  MaterialMeshParams p;
  p.outside_label = 1;
  MaterialMeshes mm = mesh_materials(tm, ms, p);
  Mesh m = mm.interfaces;
  // A hole: drop one face. A face separating a label from itself: relabel one.
  m.faces.pop_back();
  for (auto& [name, v] : m.face_ints) v.pop_back();
  m.face_ints["label_b"][0] = m.face_ints["label_a"][0];
  const InterfaceQuality q = interface_quality(m);
  EXPECT_EQ(q.boundary_edges, 3u);
  EXPECT_EQ(q.self_faces, 1u);
  EXPECT_GE(q.bad_edges, 3u);
  const auto failed = check_interface_requirements(q, "watertight,labels_consistent,manifold,rr_min>=0.0");
  auto count = [&](const std::string& key) {
    std::size_t n = 0;
    for (const auto& f : failed) n += f.rfind(key, 0) == 0;
    return n;
  };
  EXPECT_EQ(count("watertight"), 2u);  // the hole, and the two materials it opens
  EXPECT_EQ(count("labels_consistent"), 1u);
  EXPECT_GE(count("manifold"), 1u);
  EXPECT_EQ(count("rr_min"), 0u);
  EXPECT_THROW(check_interface_requirements(q, "frob"), UsageError);
  Mesh plain;
  plain.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  plain.faces = {{0, 1, 2}};
  EXPECT_FALSE(is_interface_mesh(plain));
  EXPECT_THROW(interface_quality(plain), InputError);
}


// A tetrahedron abcd with its four face neighbours: neighbour k lies across
// the face opposite corner k, its apex a unit above that face's centroid
// (away from d's side), so the neighbours are well shaped.
TetMesh tet_with_neighbours(const Vec3& d, const std::array<int, 4>& nb_labels, int own) {
  TetMesh tm;
  tm.points = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), d};
  tm.tets.push_back({0, 1, 2, 3});
  tm.neighbours.push_back({1, 2, 3, 4});
  tm.labels.push_back(own);
  const Vec3 centre = (tm.points[0] + tm.points[1] + tm.points[2] + tm.points[3]) * 0.25;
  for (int k = 0; k < 4; ++k) {
    std::array<int, 4> v{};
    int m = 0;
    for (int i = 0; i < 4; ++i)
      if (i != k) v[std::size_t(m++)] = i;
    const Vec3 &p = tm.points[std::size_t(v[0])], &q = tm.points[std::size_t(v[1])], &r = tm.points[std::size_t(v[2])];
    Vec3 n = normalized(cross(q - p, r - p));
    const Vec3 fc = (p + q + r) / 3.0;
    if (dot(n, fc - centre) < 0) n = -n;
    tm.points.push_back(fc + n);
    v[3] = int(tm.points.size()) - 1;
    tm.tets.push_back(v);
    tm.neighbours.push_back({0, -1, -1, -1});
    tm.labels.push_back(nb_labels[std::size_t(k)]);
  }
  return tm;
}

TEST(TetLabelMaterials, SliverSpikesTakeTheNeighboursLabel) {
  const Vec3 flat(1, 1, 0.05), tall(0.3, 0.3, 0.9);
  {
    // The frog's case: a sliver of material 1 between 15 (two faces), 10 and 1.
    TetMesh tm = tet_with_neighbours(flat, {15, 15, 10, 1}, 1);
    ASSERT_LT(tet_dihedral_range(tm.points[0], tm.points[1], tm.points[2], tm.points[3]).min, 15.0);
    EXPECT_EQ(relabel_sliver_spikes(tm, 0, 15), 1u);
    EXPECT_EQ(tm.labels[0], 15);
    const std::array<int, 4> around{15, 15, 10, 1};
    for (int k = 1; k <= 4; ++k) EXPECT_EQ(tm.labels[std::size_t(k)], around[std::size_t(k - 1)]);
  }
  {
    // A well-shaped tetrahedron keeps its label (its circumcentre is near).
    TetMesh tm = tet_with_neighbours(tall, {15, 15, 10, 1}, 1);
    ASSERT_GT(tet_dihedral_range(tm.points[0], tm.points[1], tm.points[2], tm.points[3]).min, 15.0);
    EXPECT_EQ(relabel_sliver_spikes(tm, 0, 15), 0u);
    EXPECT_EQ(tm.labels[0], 1);
  }
  {
    // A sliver lying on an interface (two faces on each side) is no spike.
    TetMesh tm = tet_with_neighbours(flat, {15, 1, 15, 1}, 1);
    EXPECT_EQ(relabel_sliver_spikes(tm, 0, 15), 0u);
    EXPECT_EQ(tm.labels[0], 1);
  }
  {
    // No other label on two faces: nothing to join.
    TetMesh tm = tet_with_neighbours(flat, {15, 10, 2, 1}, 1);
    EXPECT_EQ(relabel_sliver_spikes(tm, 0, 15), 0u);
  }
  {
    // Hull faces count as the outside label; a tie goes to the smaller label.
    TetMesh tm = tet_with_neighbours(flat, {15, 15, 10, 10}, 1);
    EXPECT_EQ(relabel_sliver_spikes(tm, 0, 15), 1u);
    EXPECT_EQ(tm.labels[0], 10);
    TetMesh hull = tet_with_neighbours(flat, {15, 15, 10, 1}, 1);
    hull.neighbours[0] = {-1, -1, 3, 4};
    EXPECT_EQ(relabel_sliver_spikes(hull, 7, 15), 1u);
    EXPECT_EQ(hull.labels[0], 7);
  }
}

}  // namespace
}  // namespace pm
