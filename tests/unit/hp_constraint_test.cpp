// HpConstraint and distribute_hp_particles (pm/sample/hp_constraint.h):
// moves across tetrahedron and hexahedron faces on exact planes, and
// particles on isosurfaces of the shared Nektar++ fields against their exact
// solutions, beside the lattice baseline (pm/baseline/lattice_iso.h).
#include "pm/sample/hp_constraint.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "nektar_fixtures.h"
#include "pm/baseline/lattice_iso.h"
#include "pm/base/error.h"
#include "test_util.h"

namespace pm {
namespace {

using test::GenBlock;
using test::GenMesh;

std::string write(const std::string& name, const std::string& text) {
  const std::string p = test::temp_dir() + "/" + name;
  test::write_text(p, text);
  return p;
}

struct Loaded {
  NektarMesh mesh;
  NektarField field;
};

// Two unit hexahedra side by side along x, the second turned 180 degrees
// about z (its local xi1 runs towards -x), with u = z (exact in Modified_A).
// u = z + a_e x + b_e on the two hexahedra e = 0, 1 (sums of Modified_A
// products): linear in each, C0 across x = 1 when a_0 + b_0 = a_1 + b_1.
Loaded two_hexes(double a0, double b0, double a1, double b1) {
  GenMesh m;
  int v[3][2][2];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) v[i][j][k] = m.vertex({double(i), double(j), double(k)});
  m.add_hex({v[0][0][0], v[1][0][0], v[1][1][0], v[0][1][0], v[0][0][1], v[1][0][1], v[1][1][1], v[0][1][1]});
  m.add_hex({v[2][1][0], v[1][1][0], v[1][0][0], v[2][0][0], v[2][1][1], v[1][1][1], v[1][0][1], v[2][0][1]});
  const std::array<std::array<double, 4>, 3> gz = {{{1, 0, 0, 0}, {1, 0, 0, 0}, {0, 1, 0, 0}}};
  GenBlock blk;
  blk.ids = "0-1";
  const std::pair<Vec3, Vec3> box[2] = {{Vec3{0, 0, 0}, Vec3{1, 1, 1}}, {Vec3{2, 1, 0}, Vec3{1, 0, 1}}};
  for (int e = 0; e < 2; ++e) {
    const std::array<std::array<double, 4>, 3> gx = {
        {{e ? b1 : b0, e ? a1 : a0, 0, 0}, {1, 0, 0, 0}, {1, 0, 0, 0}}};
    const auto cz = test::hex_product_coeffs(gz, box[e].first, box[e].second);
    const auto cx = test::hex_product_coeffs(gx, box[e].first, box[e].second);
    for (std::size_t k = 0; k < cz.size(); ++k) blk.coeffs.push_back(cz[k] + cx[k]);
  }
  char tag[96];
  std::snprintf(tag, sizeof tag, "hpc_hex2_%g_%g_%g_%g", a0, b0, a1, b1);
  return {read_nektar_mesh(write(std::string(tag) + ".xml", test::mesh_xml(m, false))),
          read_nektar_field(write(std::string(tag) + ".fld", test::field_xml({blk})))};
}
Loaded two_hexes_linear(double ax) { return two_hexes(ax, 0, ax, 0); }
Loaded two_hexes_linear_z() { return two_hexes_linear(0); }

Loaded shared(const std::string& dir, const std::string& name) {
  return {read_nektar_mesh(dir + "/" + name + ".xml"), read_nektar_field(dir + "/" + name + ".fld")};
}

// A move on the plane z = c across the shared face lands in the other
// hexahedron at exactly from.x + step (the plane's tangent step is exact).
TEST(HpConstraint, MoveCrossesAHexFaceOnAnExactPlane) {
  const Loaded t = two_hexes_linear_z();
  const HpField f(t.mesh, t.field, "u");
  const HpConstraint c(f, 0.3, false);
  HpConstraint::Point p, q;
  Probe pr;
  ASSERT_TRUE(c.place_reference(0, {0.8, 0.1, 0.5}, 20, p, pr));
  EXPECT_EQ(p.s.element, 0);
  EXPECT_NEAR(p.x.z, 0.3, 1e-12);
  EXPECT_NEAR(norm(p.n - Vec3{0, 0, 1}), 0, 1e-12);
  const Vec3 step{0.2, 0.05, 0};  // from x = 0.9 to x = 1.1
  ASSERT_TRUE(c.move(p, step, 6, 0, q, pr));
  EXPECT_EQ(q.s.element, 1);
  EXPECT_TRUE(f.contains(1, q.s.xi, 1e-12));
  EXPECT_NEAR(norm(q.x - (p.x + step)), 0, 1e-12);
  EXPECT_NEAR(norm(f.position(1, q.s.xi) - q.x), 0, 1e-14);
  EXPECT_LE(std::fabs(q.s.residual), 1e-12);
  // Across the outer boundary x = 2 the point stops on the boundary face.
  ASSERT_TRUE(c.move(q, {1.5, 0, 0}, 6, 0, p, pr));
  EXPECT_EQ(p.s.element, 1);
  EXPECT_NEAR(p.x.x, 2, 1e-12);
  EXPECT_NEAR(p.x.z, 0.3, 1e-12);
}

// The plane u = z + x/4 = 0.6 meets the wall x = 2 obliquely: a move out
// through the wall ends on the line x = 2, z = 0.1 (Newton within the
// wall's plane), keeping the move's y.
TEST(HpConstraint, SlidesAlongAnObliqueBoundaryFace) {
  const Loaded t = two_hexes_linear(0.25);
  const HpField f(t.mesh, t.field, "u");
  const HpConstraint c(f, 0.6, false);
  HpConstraint::Point p, q;
  Probe pr;
  ASSERT_TRUE(c.place({1.8, 0.5, 0.2}, HpConstraint::Point{}, 20, 0, p, pr));
  EXPECT_EQ(p.s.element, 1);
  EXPECT_NEAR(p.x.z + 0.25 * p.x.x, 0.6, 1e-12);
  const Vec3 step = c.tangent(p, Vec3{0.5, 0.1, 0});
  ASSERT_TRUE(c.move(p, step, 6, 0, q, pr));
  EXPECT_NEAR(q.x.x, 2, 1e-12);
  EXPECT_NEAR(q.x.z, 0.1, 1e-12);
  EXPECT_NEAR(q.x.y, p.x.y + step.y, 1e-12);
}

// u = z + 2 |x - 1| has a kink at the shared face x = 1 steeper than 45
// degrees, where Newton with either side's gradient overshoots across the
// face and back, converging only linearly (|x - 1| x 0.6 per step): from
// points above the ridge, 6 steps still reach the exact surface
// z = 0.5 - 2 |x - 1| (once stalled, Newton goes on within the face).
TEST(HpConstraint, ProjectsOntoAKinkAtAnElementFace) {
  const Loaded t = two_hexes(-2, 2, 2, -2);
  const HpField f(t.mesh, t.field, "u");
  const HpConstraint c(f, 0.5, false);
  int on_face = 0;
  for (int i = 0; i <= 10; ++i)
    for (int k = 0; k <= 10; ++k) {
      const Vec3 x0{0.9 + 0.02 * i, 0.5, 0.55 + 0.04 * k};  // above the ridge: u > 0.5
      HpConstraint::Point p;
      Probe pr;
      ASSERT_TRUE(c.place(x0, HpConstraint::Point{}, 6, 0, p, pr)) << x0.x << " " << x0.z;
      EXPECT_NEAR(p.x.z, 0.5 - 2 * std::fabs(p.x.x - 1), 1e-12) << x0.x << " " << x0.z;
      on_face += std::fabs(p.x.x - 1) < 1e-9;
    }
  EXPECT_GT(on_face, 0);
}

// chan3D's six tetrahedra: a tangent move on the exact plane z = 1/sqrt(2)
// (u = 1 - z^2 = 1/2) crosses tetrahedron faces and stays exact.
TEST(HpConstraint, MoveCrossesTetFacesOnChan3D) {
  PM_REQUIRE_SHARED(dir, "nektar-highorder");
  const Loaded t = shared(dir, "chan3D");
  const HpField f(t.mesh, t.field, "u");
  const HpConstraint c(f, 0.5, false);
  const double zs = 1 / std::sqrt(2.0);
  HpConstraint::Point p, q;
  Probe pr;
  ASSERT_TRUE(c.place({-0.9, -0.8, 0.7}, HpConstraint::Point{}, 20, 0, p, pr));
  EXPECT_NEAR(p.x.z, zs, 1e-12);
  std::set<int> visited{p.s.element};
  const Vec3 step{0.09, 0.08, 0};
  for (int k = 0; k < 20; ++k) {
    ASSERT_TRUE(c.move(p, step, 6, 0, q, pr)) << k;
    EXPECT_NEAR(norm(q.x - (p.x + step)), 0, 1e-11) << k;
    EXPECT_NEAR(q.x.z, zs, 1e-12) << k;
    EXPECT_LE(std::fabs(q.s.residual), 1e-12);
    EXPECT_TRUE(f.contains(q.s.element, q.s.xi, 1e-12));
    visited.insert(q.s.element);
    p = q;
  }
  EXPECT_GE(visited.size(), 2u);  // the diagonal walk crossed at least one face
}

// Nearest-neighbour distances (brute force; N is small here).
std::vector<double> nearest(const std::vector<Vec3>& x) {
  std::vector<double> d(x.size(), 1e300);
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = 0; j < x.size(); ++j)
      if (i != j) d[i] = std::min(d[i], norm(x[i] - x[j]));
  return d;
}
double cv(const std::vector<double>& v) {
  double m = 0, s = 0;
  for (double a : v) m += a;
  m /= double(v.size());
  for (double a : v) s += (a - m) * (a - m);
  return std::sqrt(s / double(v.size())) / m;
}

// World distance from x to the nearest interior face (shared by two
// elements) of element e.
double interior_face_distance(const HpField& f, int e, const Vec3& x) {
  const std::vector<Vec3> v = f.element_vertices(e);
  static const int tf[4][3] = {{0, 1, 2}, {0, 1, 3}, {1, 2, 3}, {0, 2, 3}};
  static const int hf[6][3] = {{0, 1, 2}, {0, 1, 5}, {1, 2, 6}, {3, 2, 6}, {0, 3, 7}, {4, 5, 6}};
  double best = 1e300;
  for (int k = 0; k < f.num_faces(e); ++k) {
    if (f.neighbour(e, k) < 0) continue;
    const int* fv = f.shape(e) == NektarShape::Tetrahedron ? tf[k] : hf[k];
    const Vec3 n = normalized(cross(v[std::size_t(fv[1])] - v[std::size_t(fv[0])], v[std::size_t(fv[2])] - v[std::size_t(fv[0])]));
    best = std::min(best, std::fabs(dot(x - v[std::size_t(fv[0])], n)));
  }
  return best;
}

// chan3D, u = 1 - z^2 = 1/2: every particle on |z| = 1/sqrt(2) to round-off,
// while the lattice baseline (FieldConvert's default lattice, modes + 1
// points per edge) is off by several percent. The surface is two 2 x 2
// squares (area 8) cut by the channel walls |x|, |y| = 1.
TEST(HpParticles, Chan3DHalfLevelAtRoundOffLatticeBaselineIsNot) {
  PM_REQUIRE_SHARED(dir, "nektar-highorder");
  const Loaded t = shared(dir, "chan3D");
  const HpField f(t.mesh, t.field, "u");
  HpParticleParams p;
  p.iso = 0.5;
  p.spacing = 0.1;
  p.progress = false;
  const HpParticleResult r = distribute_hp_particles(f, p);
  const double zs = 1 / std::sqrt(2.0);
  ASSERT_GT(r.positions.size(), 100u);
  double worst = 0;
  std::set<int> elems;
  for (std::size_t i = 0; i < r.positions.size(); ++i) {
    worst = std::max(worst, std::fabs(std::fabs(r.positions[i].z) - zs));
    EXPECT_LE(r.residual[i], 1e-12);
    elems.insert(r.element[i]);
  }
  // |u - c| <= 1e-12 and |du/dz| = sqrt(2) at the surface: |dz| <= 7.1e-13.
  EXPECT_LE(worst, 1e-12);
  EXPECT_TRUE(r.converged);

  const LatticeIsoResult base = lattice_isosurface(f, 0.5);
  double base_worst = 0;
  for (const Vec3& x : base.mesh.vertices) base_worst = std::max(base_worst, std::fabs(std::fabs(x.z) - zs));
  EXPECT_GT(base_worst / zs, 0.03);  // the measurement: 0.667 instead of 0.7071, 5.7%
  // Every element the surface crosses (the baseline sees all six) holds particles.
  std::set<int> base_elems;
  for (double e : base.mesh.vertex_scalars.at("element")) base_elems.insert(int(e));
  for (int e : base_elems) EXPECT_TRUE(elems.count(e)) << "element " << e;

  // Spacing: nearest-neighbour CV, overall and within one spacing of an
  // interior element face (no gap or pile-up there).
  const std::vector<double> d = nearest(r.positions);
  std::vector<double> near_face, rest;
  for (std::size_t i = 0; i < d.size(); ++i) {
    const int e = f.element_index(r.element[i]);
    (interior_face_distance(f, e, r.positions[i]) < p.spacing ? near_face : rest).push_back(d[i]);
  }
  EXPECT_LE(cv(d), 0.1);
  ASSERT_GT(near_face.size(), 20u);
  EXPECT_LE(cv(near_face), std::max(0.1, 1.25 * cv(rest))) << cv(near_face) << " vs " << cv(rest);
  // Count in the interior (one spacing off the walls, where the open edge
  // holds a denser row): population control keeps it within [0.86, 1.27] of
  // the hexagonal estimate area / (sqrt(3)/2 s^2) (pm/sample/particles.h).
  const double a = 1 - p.spacing;
  std::size_t inner = 0;
  for (const Vec3& x : r.positions) inner += std::fabs(x.x) < a && std::fabs(x.y) < a;
  const double estimate = 2 * (2 * a) * (2 * a) / (std::sqrt(3.0) / 2 * p.spacing * p.spacing);
  EXPECT_GE(double(inner), 0.86 * estimate);
  EXPECT_LE(double(inner), 1.27 * estimate);
}

// Coarse-to-fine (4 levels from the default start, 4 x the field's
// resolution 2/3) ends on the same exact surface, with particles in all six
// elements and the interior count in population control's band.
TEST(HpParticles, Chan3DCoarseToFine) {
  PM_REQUIRE_SHARED(dir, "nektar-highorder");
  const Loaded t = shared(dir, "chan3D");
  const HpField f(t.mesh, t.field, "u");
  HpParticleParams p;
  p.iso = 0.5;
  p.spacing = 0.1;
  p.coarse_to_fine = true;
  p.progress = false;
  const HpParticleResult r = distribute_hp_particles(f, p);
  EXPECT_EQ(r.levels, 5);
  double worst = 0;
  for (const Vec3& x : r.positions) worst = std::max(worst, std::fabs(std::fabs(x.z) - 1 / std::sqrt(2.0)));
  EXPECT_LE(worst, 1e-12);
  EXPECT_EQ(std::set<int>(r.element.begin(), r.element.end()).size(), 6u);
  const double a = 1 - p.spacing;
  std::size_t inner = 0;
  for (const Vec3& x : r.positions) inner += std::fabs(x.x) < a && std::fabs(x.y) < a;
  const double estimate = 2 * (2 * a) * (2 * a) / (std::sqrt(3.0) / 2 * p.spacing * p.spacing);
  EXPECT_GE(double(inner), 0.86 * estimate);
  EXPECT_LE(double(inner), 1.27 * estimate);
  EXPECT_LE(cv(nearest(r.positions)), 0.1);
}

// Tet_channel_m3, w = y(1 - y) = 0.2: y = (1 ± sqrt(0.2)) / 2 to round-off
// in all 48 tetrahedra.
TEST(HpParticles, TetChannelM3ParabolaLevelAtRoundOff) {
  PM_REQUIRE_SHARED(dir, "nektar-highorder");
  const Loaded t = shared(dir, "Tet_channel_m3");
  const HpField f(t.mesh, t.field, "w");
  HpParticleParams p;
  p.iso = 0.2;
  p.spacing = 0.1;
  p.progress = false;
  const HpParticleResult r = distribute_hp_particles(f, p);
  ASSERT_GT(r.positions.size(), 100u);
  const double y0 = (1 - std::sqrt(0.2)) / 2, y1 = (1 + std::sqrt(0.2)) / 2;
  double worst = 0;
  for (const Vec3& x : r.positions) worst = std::max(worst, std::min(std::fabs(x.y - y0), std::fabs(x.y - y1)));
  // |w - c| <= 1e-12 and |dw/dy| = sqrt(0.2) there: |dy| <= 2.3e-12.
  EXPECT_LE(worst, 2.3e-12);
  std::set<int> elems(r.element.begin(), r.element.end());
  const LatticeIsoResult base = lattice_isosurface(f, 0.2);
  for (double e : base.mesh.vertex_scalars.at("element")) EXPECT_TRUE(elems.count(int(e))) << "element " << e;
  EXPECT_LE(cv(nearest(r.positions)), 0.1);
}

// Hex_channel_C0helmsmoothing has no closed form: particles sit on our own
// evaluator's level to the Newton tolerance, inside their hexahedra.
TEST(HpParticles, HexChannelOnTheLevelInsideTheElements) {
  PM_REQUIRE_SHARED(dir, "nektar-highorder");
  const Loaded t = shared(dir, "Hex_channel_C0helmsmoothing");
  const HpField f(t.mesh, t.field, "u");
  HpParticleParams p;
  p.iso = 0.5;
  p.spacing = 0.1;
  p.progress = false;
  const HpParticleResult r = distribute_hp_particles(f, p);
  ASSERT_GT(r.positions.size(), 50u);
  std::set<int> elems;
  for (std::size_t i = 0; i < r.positions.size(); ++i) {
    const int e = f.element_index(r.element[i]);
    ASSERT_GE(e, 0);
    elems.insert(e);
    EXPECT_TRUE(f.contains(e, r.xi[i], 1e-12));
    EXPECT_LE(std::fabs(f.ref_value(e, r.xi[i]) - 0.5), 1e-12);
    EXPECT_NEAR(norm(f.position(e, r.xi[i]) - r.positions[i]), 0, 1e-13);
  }
  EXPECT_GE(elems.size(), 2u);
}

TEST(HpParticles, RefusesBadParametersAndMissingSurfaces) {
  const Loaded t = two_hexes_linear_z();
  const HpField f(t.mesh, t.field, "u");
  HpParticleParams p;
  p.iso = 0.5;
  p.progress = false;
  p.spacing = 0;
  EXPECT_THROW(distribute_hp_particles(f, p), UsageError);
  p.spacing = 100;
  EXPECT_THROW(distribute_hp_particles(f, p), UsageError);
  p.spacing = 0.2;
  p.seed_points = 1;
  EXPECT_THROW(distribute_hp_particles(f, p), UsageError);
  p.seed_points = 0;
  p.iso = 3;  // u = z lies in [0, 1]
  EXPECT_THROW(distribute_hp_particles(f, p), InputError);
}

}  // namespace
}  // namespace pm
