// HpField (pm/field/hp_field.h): bases against closed forms and the exact
// solutions of the shared Nektar++ fields, world derivatives against finite
// differences, point location, adjacency and face crossing.
#include "pm/field/hp_field.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "nektar_fixtures.h"
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

double max_abs(const Mat3& a) {
  double m = 0;
  for (const auto& r : a.m)
    for (double v : r) m = std::max(m, std::fabs(v));
  return m;
}

// ---- generated fixtures --------------------------------------------------------

// g1(x) g2(y) g3(z), cubic in each variable.
const std::array<std::array<double, 4>, 3> kG = {{{1, 1, -2, 0.5}, {2, -1, 0, 1}, {0.3, 0, 1, 0}}};
double poly(const std::array<double, 4>& a, double t, int d = 0) {
  if (d == 0) return a[0] + t * (a[1] + t * (a[2] + t * a[3]));
  if (d == 1) return a[1] + t * (2 * a[2] + t * 3 * a[3]);
  return 2 * a[2] + 6 * a[3] * t;
}
double g_val(const Vec3& x) { return poly(kG[0], x.x) * poly(kG[1], x.y) * poly(kG[2], x.z); }
Vec3 g_grad(const Vec3& x) {
  const double a = poly(kG[0], x.x), b = poly(kG[1], x.y), c = poly(kG[2], x.z);
  return {poly(kG[0], x.x, 1) * b * c, a * poly(kG[1], x.y, 1) * c, a * b * poly(kG[2], x.z, 1)};
}
Mat3 g_hess(const Vec3& x) {
  double v[3], d[3], dd[3];
  for (int k = 0; k < 3; ++k) {
    v[k] = poly(kG[k], x[k]);
    d[k] = poly(kG[k], x[k], 1);
    dd[k] = poly(kG[k], x[k], 2);
  }
  Mat3 H;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double p = 1;
      for (int k = 0; k < 3; ++k) p *= (i == k && j == k) ? dd[k] : (i == k || j == k) ? d[k] : v[k];
      H.m[i][j] = p;
    }
  return H;
}

struct TwoHexes {
  GenMesh g;
  NektarMesh mesh;
  NektarField field;
};

// Two unit hexahedra along x, the second turned 180 degrees about z, with the
// product field above (exact in 4 modes).
TwoHexes two_hexes(bool compressed) {
  TwoHexes t;
  GenMesh& m = t.g;
  int v[3][2][2];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) v[i][j][k] = m.vertex({double(i), double(j), double(k)});
  m.add_hex({v[0][0][0], v[1][0][0], v[1][1][0], v[0][1][0], v[0][0][1], v[1][0][1], v[1][1][1], v[0][1][1]});
  m.add_hex({v[2][1][0], v[1][1][0], v[1][0][0], v[2][0][0], v[2][1][1], v[1][1][1], v[1][0][1], v[2][0][1]});
  GenBlock blk;
  blk.ids = "0-1";
  for (const auto& lohi : {std::make_pair(Vec3{0, 0, 0}, Vec3{1, 1, 1}), std::make_pair(Vec3{2, 1, 0}, Vec3{1, 0, 1})}) {
    const auto c = test::hex_product_coeffs(kG, lohi.first, lohi.second);
    blk.coeffs.insert(blk.coeffs.end(), c.begin(), c.end());
  }
  const std::string tag = compressed ? "z" : "p";
  t.mesh = read_nektar_mesh(write("hex2" + tag + ".xml", test::mesh_xml(m, compressed)));
  t.field = read_nektar_field(write("hex2" + tag + ".fld", test::field_xml({blk})));
  return t;
}

// A quadratic with every second derivative non-zero.
double q_val(const Vec3& x) {
  return 1 + x.x - 2 * x.y + 3 * x.z + x.x * x.x - x.x * x.y + 2 * x.y * x.z - x.z * x.z + 0.5 * x.x * x.z;
}
Vec3 q_grad(const Vec3& x) {
  return {1 + 2 * x.x - x.y + 0.5 * x.z, -2 - x.x + 2 * x.z, 3 + 2 * x.y - 2 * x.z + 0.5 * x.x};
}
Mat3 q_hess() {
  Mat3 H;
  H.m = {{{2, -1, 0.5}, {-1, 0, 2}, {0.5, 2, -2}}};
  return H;
}

struct TwoTets {
  NektarMesh mesh;
  NektarField field;
};

// A = (a0 a1 a2 a3), B = (a1 a2 a3 b3); B's face 0 is A's face 2.
TwoTets two_tets(bool compressed) {
  GenMesh m;
  const std::array<Vec3, 5> p = {Vec3{0, 0, 0}, Vec3{1, 0, 0}, Vec3{0.2, 1, 0}, Vec3{0.1, 0.3, 1}, Vec3{1, 1, 1.2}};
  int id[5];
  for (int k = 0; k < 5; ++k) id[k] = m.vertex(p[k]);
  m.add_tet({id[0], id[1], id[2], id[3]});
  m.add_tet({id[1], id[2], id[3], id[4]});
  GenBlock blk;
  blk.shape = "Tetrahedron";
  blk.basis = "Modified_A,Modified_B,Modified_C";
  blk.modes = "UNIORDER:3,3,3";
  blk.ids = "0,1";
  for (const auto& c : {test::tet_p2_coeffs(q_val, {p[0], p[1], p[2], p[3]}), test::tet_p2_coeffs(q_val, {p[1], p[2], p[3], p[4]})})
    blk.coeffs.insert(blk.coeffs.end(), c.begin(), c.end());
  const std::string tag = compressed ? "z" : "p";
  TwoTets t;
  t.mesh = read_nektar_mesh(write("tet2" + tag + ".xml", test::mesh_xml(m, compressed)));
  t.field = read_nektar_field(write("tet2" + tag + ".fld", test::field_xml({blk})));
  return t;
}

// Random reference point inside the element.
Vec3 random_xi(NektarShape s, std::mt19937& rng) {
  std::uniform_real_distribution<double> U(-1, 1);
  for (;;) {
    const Vec3 xi{U(rng), U(rng), U(rng)};
    if (s == NektarShape::Hexahedron || xi.x + xi.y + xi.z <= -1) return xi;
  }
}

// ---- bases ---------------------------------------------------------------------

TEST(HpBasis, ModifiedAClosedForms) {
  double v[5], d[5], dd[5];
  for (double z : {-1.0, -0.3, 0.0, 0.7, 1.0}) {
    hp::modified_a(5, z, v, d, dd);
    EXPECT_NEAR(v[0], 0.5 * (1 - z), 1e-15);
    EXPECT_NEAR(v[1], 0.5 * (1 + z), 1e-15);
    EXPECT_NEAR(v[2], 0.25 * (1 - z * z), 1e-15);                          // P0^(1,1) = 1
    EXPECT_NEAR(v[3], 0.25 * (1 - z * z) * 2 * z, 1e-15);                  // P1^(1,1) = 2z
    EXPECT_NEAR(v[4], 0.25 * (1 - z * z) * (15 * z * z - 3) / 4, 1e-15);  // P2^(1,1)
    EXPECT_NEAR(d[3], 0.5 * (1 - 3 * z * z), 1e-14);
    EXPECT_NEAR(dd[3], -3 * z, 1e-14);
  }
}

TEST(HpBasis, TetVertexAndEdgeModesAreBarycentricProducts) {
  // 3 modes: the hierarchical P2 basis (see nektar_fixtures.h).
  std::mt19937 rng(3);
  for (int mode = 0; mode < 10; ++mode) {
    std::vector<double> c(10, 0.0);
    c[mode] = 1;
    for (int k = 0; k < 20; ++k) {
      const Vec3 xi = random_xi(NektarShape::Tetrahedron, rng);
      const double l0 = -0.5 * (1 + xi.x + xi.y + xi.z), l1 = 0.5 * (1 + xi.x), l2 = 0.5 * (1 + xi.y),
                   l3 = 0.5 * (1 + xi.z);
      const double want[10] = {l0, l3, l0 * l3, l2, l2 * l3, l0 * l2, l1, l1 * l3, l1 * l2, l0 * l1};
      EXPECT_NEAR(hp::tet_evaluate({3, 3, 3}, c.data(), xi, nullptr, nullptr), want[mode], 1e-15) << mode;
      EXPECT_NEAR(hp::tet_value_collapsed({3, 3, 3}, c.data(), xi), want[mode], 1e-13) << mode;
    }
  }
}

TEST(HpBasis, TetDivisionFreeFormEqualsCollapsedCoordinates) {
  // The evaluator's polynomial form against Nektar++'s backward transform in
  // collapsed coordinates (with its singular-vertex split), random
  // coefficients, 2..8 modes and an anisotropic P < Q < R.
  std::mt19937 rng(7);
  std::normal_distribution<double> N(0, 1);
  for (const std::array<int, 3> n : {std::array<int, 3>{2, 2, 2}, {4, 4, 4}, {6, 6, 6}, {8, 8, 8}, {2, 3, 4}, {3, 4, 6}}) {
    std::vector<double> c(nektar_num_coeffs(NektarShape::Tetrahedron, n));
    for (double& v : c) v = N(rng);
    double scale = 0;
    for (double v : c) scale += std::fabs(v);
    for (int k = 0; k < 200; ++k) {
      const Vec3 xi = random_xi(NektarShape::Tetrahedron, rng);
      if (-xi.y - xi.z < 1e-3 || 1 - xi.z < 1e-3) continue;  // collapsed form loses digits there
      EXPECT_NEAR(hp::tet_evaluate(n, c.data(), xi, nullptr, nullptr), hp::tet_value_collapsed(n, c.data(), xi),
                  1e-12 * scale)
          << n[0] << n[1] << n[2];
    }
  }
}

TEST(HpBasis, TetDerivativesMatchFiniteDifferencesIncludingTheCollapsedEdge) {
  std::mt19937 rng(11);
  std::normal_distribution<double> N(0, 1);
  const std::array<int, 3> n{5, 5, 5};
  std::vector<double> c(nektar_num_coeffs(NektarShape::Tetrahedron, n));
  for (double& v : c) v = N(rng);
  // Interior points, points on the collapsed edge v2-v3 (xi1 = -1, xi2 = -xi3)
  // and the top vertex: the polynomial form has no singularity there.
  std::vector<Vec3> pts;
  for (int k = 0; k < 30; ++k) pts.push_back(random_xi(NektarShape::Tetrahedron, rng));
  for (double t : {-1.0, -0.5, 0.0, 0.9, 1.0}) pts.push_back({-1, -t, t});
  const double h = 1e-5;
  for (const Vec3& xi : pts) {
    Vec3 g;
    Mat3 H;
    const double f = hp::tet_evaluate(n, c.data(), xi, &g, &H);
    EXPECT_DOUBLE_EQ(f, hp::tet_evaluate(n, c.data(), xi, nullptr, nullptr));
    for (int a = 0; a < 3; ++a) {
      Vec3 e;
      e[a] = h;
      Vec3 gp, gm;
      Mat3 Hd;
      const double fp = hp::tet_evaluate(n, c.data(), xi + e, &gp, &Hd);
      const double fm = hp::tet_evaluate(n, c.data(), xi - e, &gm, &Hd);
      EXPECT_NEAR(g[a], (fp - fm) / (2 * h), 1e-7);
      for (int b = 0; b < 3; ++b) EXPECT_NEAR(H.m[b][a], (gp[b] - gm[b]) / (2 * h), 1e-6);
    }
  }
}

// ---- generated fields: exact ------------------------------------------------------

TEST(HpField, HexProductCubicExactInWorldSpace) {
  for (bool compressed : {false, true}) {
    const TwoHexes t = two_hexes(compressed);
    const HpField f(t.mesh, t.field, "u");
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> U(0, 1);
    for (int k = 0; k < 200; ++k) {
      const Vec3 x{2 * U(rng), U(rng), U(rng)};
      Vec3 g;
      Mat3 H;
      const double v = f.evaluate(x, g, H);
      EXPECT_NEAR(v, g_val(x), 1e-12);
      EXPECT_NEAR(norm(g - g_grad(x)), 0, 1e-11);
      EXPECT_NEAR(max_abs(H - g_hess(x)), 0, 1e-10);
    }
  }
}

TEST(HpField, TetQuadraticExactInWorldSpace) {
  for (bool compressed : {false, true}) {
    const TwoTets t = two_tets(compressed);
    const HpField f(t.mesh, t.field, "u");
    std::mt19937 rng(9);
    for (int e = 0; e < 2; ++e)
      for (int k = 0; k < 100; ++k) {
        const Vec3 xi = random_xi(NektarShape::Tetrahedron, rng);
        const HpSample s = f.sample(e, xi);
        EXPECT_NEAR(s.f, q_val(s.x), 1e-13);
        EXPECT_NEAR(norm(s.grad - q_grad(s.x)), 0, 1e-12);
        EXPECT_NEAR(max_abs(s.hess - q_hess()), 0, 1e-11);
        // J K = I and the world point maps back.
        EXPECT_NEAR(max_abs(s.J * s.K - Mat3::identity()), 0, 1e-14);
        Vec3 back;
        ASSERT_TRUE(f.inverse_map(e, s.x, back));
        EXPECT_NEAR(norm(back - xi), 0, 1e-14);
      }
  }
}

TEST(HpField, DistortedHexWorldDerivativesMatchFiniteDifferences) {
  // One trilinear (non-affine) hexahedron and random coefficients, 5 modes:
  // the world gradient K^T grad F* and Hessian K^T (H* - sum g_a d2T^a) K
  // against central differences of the world value.
  GenMesh m;
  const std::array<Vec3, 8> p = {Vec3{0, 0, 0}, Vec3{1.2, 0.1, 0}, Vec3{1.0, 1.1, 0.2}, Vec3{-0.1, 0.9, 0},
                                 Vec3{0.1, 0, 1},  Vec3{1.1, 0.2, 0.9}, Vec3{1.3, 1.2, 1.3}, Vec3{0, 1, 1.1}};
  std::array<int, 8> id;
  for (int k = 0; k < 8; ++k) id[k] = m.vertex(p[k]);
  m.add_hex(id);
  GenBlock blk;
  blk.modes = "UNIORDER:5,5,5";
  std::mt19937 rng(13);
  std::normal_distribution<double> N(0, 1);
  for (int k = 0; k < 125; ++k) blk.coeffs.push_back(N(rng) / (1 + k % 5 + (k / 5) % 5 + k / 25));
  const NektarMesh mesh = read_nektar_mesh(write("dhex.xml", test::mesh_xml(m, true)));
  const HpField f(mesh, read_nektar_field(write("dhex.fld", test::field_xml({blk}))), "u");
  const double h = 1e-5;
  for (int k = 0; k < 30; ++k) {
    const Vec3 xi = 0.9 * random_xi(NektarShape::Hexahedron, rng);
    const HpSample s = f.sample(0, xi);
    const RefPoint loc = f.locate(s.x);
    ASSERT_EQ(loc.elem, 0);
    EXPECT_NEAR(norm(loc.xi - xi), 0, 1e-12);
    for (int a = 0; a < 3; ++a) {
      Vec3 e;
      e[a] = h;
      Vec3 gp, gm;
      Mat3 Hd;
      const double fp = f.evaluate(s.x + e, gp, Hd), fm = f.evaluate(s.x - e, gm, Hd);
      EXPECT_NEAR(s.grad[a], (fp - fm) / (2 * h), 1e-7 * (1 + norm(s.grad)));
      for (int b = 0; b < 3; ++b) EXPECT_NEAR(s.hess.m[b][a], (gp[b] - gm[b]) / (2 * h), 1e-6 * (1 + max_abs(s.hess)));
    }
  }
}

// ---- shared Nektar++ fields: exact solutions ------------------------------------------

struct Exact {
  const char* var;
  double (*f)(const Vec3&);
  Vec3 (*g)(const Vec3&);
  double hyy, hzz;  // the only non-zero Hessian entries of these solutions
};

void check_exact(const std::string& name, const std::vector<Exact>& cases) {
  PM_REQUIRE_SHARED(dir, "nektar-highorder");
  const NektarMesh mesh = read_nektar_mesh(dir + "/" + name + ".xml");
  const NektarField fld = read_nektar_field(dir + "/" + name + ".fld");
  for (const Exact& c : cases) {
    const HpField f(mesh, fld, c.var);
    std::mt19937 rng(17);
    for (int e = 0; e < f.num_elements(); ++e)
      for (int k = 0; k < 20; ++k) {
        const Vec3 xi = random_xi(f.shape(e), rng);
        const HpSample s = f.sample(e, xi);
        EXPECT_NEAR(s.f, c.f(s.x), 1e-12) << name << " " << c.var;
        EXPECT_NEAR(norm(s.grad - c.g(s.x)), 0, 1e-11) << name << " " << c.var;
        Mat3 want;
        want.m[1][1] = c.hyy;
        want.m[2][2] = c.hzz;
        EXPECT_NEAR(max_abs(s.hess - want), 0, 1e-10) << name << " " << c.var;
      }
  }
}

TEST(HpFieldShared, TetChannelM3ExactSolutions) {
  check_exact("Tet_channel_m3",
              {{"w", [](const Vec3& x) { return x.y * (1 - x.y); }, [](const Vec3& x) { return Vec3{0, 1 - 2 * x.y, 0}; }, -2, 0},
               {"p", [](const Vec3& x) { return -2 * (x.z - 1); }, [](const Vec3&) { return Vec3{0, 0, -2}; }, 0, 0},
               {"u", [](const Vec3&) { return 0.0; }, [](const Vec3&) { return Vec3{}; }, 0, 0}});
}

TEST(HpFieldShared, Chan3DExactSolutions) {
  check_exact("chan3D",
              {{"u", [](const Vec3& x) { return 1 - x.z * x.z; }, [](const Vec3& x) { return Vec3{0, 0, -2 * x.z}; }, 0, -2},
               {"p", [](const Vec3& x) { return 2 * (1 - x.x); }, [](const Vec3&) { return Vec3{-2, 0, 0}; }, 0, 0}});
}

TEST(HpFieldShared, ContinuousAcrossEveryInteriorFace) {
  // Tet_channel (Galerkin) and Hex_channel (C0 Helmholtz smoothing) are C0
  // fields: both sides of every shared face agree to round-off, which fails
  // for any local vertex order other than Nektar++'s.
  PM_REQUIRE_SHARED(dir, "nektar-highorder");
  for (const char* name : {"Tet_channel_m3", "Hex_channel_C0helmsmoothing"}) {
    const NektarMesh mesh = read_nektar_mesh(dir + "/" + name + ".xml");
    const NektarField fld = read_nektar_field(dir + "/" + name + ".fld");
    const HpField f(mesh, fld, "u");
    std::mt19937 rng(19);
    std::uniform_real_distribution<double> U(0, 1);
    int shared = 0;
    double scale = 0;
    for (int e = 0; e < f.num_elements(); ++e) scale = std::max(scale, std::fabs(f.ref_value(e, {-0.5, -0.5, -0.5})));
    for (int e = 0; e < f.num_elements(); ++e)
      for (int face = 0; face < f.num_faces(e); ++face) {
        const int nb = f.neighbour(e, face);
        if (nb < 0) continue;
        ++shared;
        const auto v = f.element_vertices(e);
        for (int k = 0; k < 5; ++k) {
          // A random point of the face, from its vertices.
          Vec3 x;
          if (f.shape(e) == NektarShape::Tetrahedron) {
            static const int fv[4][3] = {{0, 1, 2}, {0, 1, 3}, {1, 2, 3}, {0, 2, 3}};
            double a = U(rng), b = U(rng);
            if (a + b > 1) {
              a = 1 - a;
              b = 1 - b;
            }
            x = (1 - a - b) * v[fv[face][0]] + a * v[fv[face][1]] + b * v[fv[face][2]];
          } else {
            static const int fv[6][4] = {{0, 1, 2, 3}, {0, 1, 5, 4}, {1, 2, 6, 5}, {3, 2, 6, 7}, {0, 3, 7, 4}, {4, 5, 6, 7}};
            const double a = U(rng), b = U(rng);
            x = (1 - a) * (1 - b) * v[fv[face][0]] + a * (1 - b) * v[fv[face][1]] + a * b * v[fv[face][2]] +
                (1 - a) * b * v[fv[face][3]];
          }
          Vec3 xa, xb;
          ASSERT_TRUE(f.inverse_map(e, x, xa));
          ASSERT_TRUE(f.inverse_map(nb, x, xb));
          EXPECT_NEAR(f.ref_value(e, xa), f.ref_value(nb, xb), 1e-12 * (1 + scale)) << name << " elem " << e << " face " << face;
        }
      }
    EXPECT_GT(shared, 0) << name;
  }
}

// ---- location, adjacency, crossing, counters -----------------------------------------

TEST(HpField, TetAdjacencyLocationAndCrossing) {
  const TwoTets t = two_tets(true);
  const HpField f(t.mesh, t.field, "u");
  int nbf = -1;
  EXPECT_EQ(f.neighbour(0, 2, &nbf), 1);
  EXPECT_EQ(nbf, 0);
  EXPECT_EQ(f.neighbour(1, 0, &nbf), 0);
  EXPECT_EQ(nbf, 2);
  for (int face : {0, 1, 3}) EXPECT_EQ(f.neighbour(0, face), -1);
  // A point of A moved just across face 2 (xi1 + xi2 + xi3 = -1).
  const Vec3 inside{-0.6, -0.3, -0.2};  // sum -1.1
  const Vec3 beyond{-0.55, -0.25, -0.15};  // sum -0.95
  EXPECT_EQ(f.exit_face(0, inside), -1);
  EXPECT_EQ(f.exit_face(0, beyond), 2);
  const RefPoint r = f.cross_face(0, 2, beyond);
  ASSERT_EQ(r.elem, 1);
  EXPECT_TRUE(f.contains(1, r.xi, 1e-12));
  EXPECT_NEAR(norm(f.position(1, r.xi) - f.position(0, beyond)), 0, 1e-14);
  EXPECT_NEAR(f.ref_value(1, r.xi), f.ref_value(0, beyond), 1e-13);  // the same quadratic
  // World location agrees and the walk from the other element finds it too.
  const Vec3 x = f.position(0, beyond);
  for (int hint : {-1, 0, 1}) {
    const RefPoint l = f.locate(x, hint);
    EXPECT_EQ(l.elem, 1);
    EXPECT_NEAR(norm(l.xi - r.xi), 0, 1e-13);
  }
  EXPECT_EQ(f.locate({5, 5, 5}).elem, -1);
  EXPECT_EQ(f.cross_face(0, 0, {-0.5, -0.5, -1.1}).elem, -1);  // boundary
}

TEST(HpField, HexAdjacencyLocationAndCrossing) {
  const TwoHexes t = two_hexes(false);
  const HpField f(t.mesh, t.field, "u");
  int nbf = -1;
  // The shared face x = 1 is local face 2 (xi1 = +1) of both hexahedra.
  EXPECT_EQ(f.neighbour(0, 2, &nbf), 1);
  EXPECT_EQ(nbf, 2);
  const Vec3 beyond{1.04, 0.3, -0.2};
  EXPECT_EQ(f.exit_face(0, beyond), 2);
  const RefPoint r = f.cross_face(0, 2, beyond);
  ASSERT_EQ(r.elem, 1);
  EXPECT_TRUE(f.contains(1, r.xi));
  EXPECT_NEAR(norm(r.xi - Vec3{0.96, -0.3, -0.2}), 0, 1e-13);  // turned 180 degrees about z
  EXPECT_NEAR(norm(f.position(1, r.xi) - f.position(0, beyond)), 0, 1e-14);
  EXPECT_NEAR(f.ref_value(1, r.xi), g_val(f.position(0, beyond)), 1e-12);
  const RefPoint l = f.locate({1.52, 0.35, 0.6}, 0);
  ASSERT_EQ(l.elem, 1);
  EXPECT_NEAR(norm(f.position(1, l.xi) - Vec3{1.52, 0.35, 0.6}), 0, 1e-14);
}

TEST(HpField, CountsForwardEvaluations) {
  const TwoTets t = two_tets(false);
  const HpField f(t.mesh, t.field, "u");
  f.reset_counters();
  f.ref_value(0, {-0.5, -0.5, -0.5});
  Vec3 g;
  Mat3 H;
  f.ref_evaluate(1, {-0.5, -0.5, -0.5}, g, H);
  EXPECT_EQ(f.field_evaluations(), 2u);
  EXPECT_EQ(f.map_evaluations(), 0u);
  f.sample(0, {-0.5, -0.5, -0.5});
  EXPECT_EQ(f.field_evaluations(), 3u);
  EXPECT_EQ(f.map_evaluations(), 1u);
  // A world-space value: location (map evaluations) plus one field evaluation.
  f.value({0.2, 0.2, 0.2});
  EXPECT_EQ(f.field_evaluations(), 4u);
  EXPECT_GE(f.map_evaluations(), 2u);
  // ScalarField view: the domain is the mesh box.
  EXPECT_EQ(f.domain().lo, (Vec3{0, 0, 0}));
  EXPECT_EQ(f.domain().hi, (Vec3{1, 1, 1.2}));
  EXPECT_GT(f.resolution(), 0);
}

}  // namespace
}  // namespace pm
