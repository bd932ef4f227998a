// The built-in Chapter 4 scenarios (pm/field/reference_scenarios.h) and
// particles on them through the reference-space constraint
// (pm/sample/hp_constraint.h): the B-spline-mapped teardrop against the
// exact sphere in reference space, and an 8th-order polynomial in one
// hexahedron against the exact polynomial.
#include "pm/field/reference_scenarios.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "pm/base/error.h"
#include "pm/sample/hp_constraint.h"

namespace pm {
namespace {

// The map's Jacobian and Hessian against central differences of T: T is
// quadratic per span in each variable, so the central difference of the
// first derivative is exact up to round-off (h = 1e-5: error ~ 1e-16 / h).
TEST(Teardrop, JacobianAndWorldHessianMatchFiniteDifferences) {
  const TeardropField f;
  const Vec3 xi{0.3, -0.4, 0.55};
  for (int e : {0, 5, 7}) {
    const HpSample s = f.sample(e, xi);
    const double h = 1e-5;
    for (int i = 0; i < 3; ++i) {
      Vec3 d;
      d[i] = h;
      const Vec3 fd = (f.sample(e, xi + d).x - f.sample(e, xi - d).x) / (2 * h);
      for (int a = 0; a < 3; ++a) EXPECT_NEAR(s.J[a][i], fd[a], 1e-9) << e << " " << a << i;
    }
    // World Hessian: derivative of the world gradient along world directions,
    // d(grad)/dx = (d grad / d xi) K.
    for (int i = 0; i < 3; ++i) {
      Vec3 d;
      d[i] = h;
      const Vec3 dg = (f.sample(e, xi + d).grad - f.sample(e, xi - d).grad) / (2 * h);
      for (int a = 0; a < 3; ++a) {
        double want = 0;
        for (int b = 0; b < 3; ++b) want += s.hess[a][b] * s.J[b][i];
        EXPECT_NEAR(dg[a], want, 1e-7) << e << " " << a << i;
      }
    }
  }
}

// A face crossing keeps u, and the C1 map keeps the world point (round-off).
TEST(Teardrop, FaceCrossingIsTheSamePoint) {
  const TeardropField f;
  const Vec3 xi{1.0 + 1e-3, 0.2, -0.3};  // just beyond face 2 (xi1 = +1) of element 0
  ASSERT_EQ(f.exit_face(0, xi), 2);
  const RefPoint r = f.cross_face(0, 2, xi);
  ASSERT_EQ(r.elem, 1);
  EXPECT_NEAR(r.xi.x, -1 + 1e-3, 1e-15);
  const Vec3 a = f.sample(0, xi).x, b = f.sample(1, r.xi).x;
  EXPECT_LE(norm(a - b), 1e-14);
  EXPECT_LT(f.cross_face(1, 2, Vec3{1.1, 0, 0}).elem, 0);  // the outer boundary
  const RefPoint l = f.locate(a, 7);
  EXPECT_EQ(l.elem, 1);
  EXPECT_LE(norm(l.xi - r.xi), 1e-12);
}

// Particles on the teardrop: every one on the sphere in reference space
// (Newton stops at |F* - r^2| <= 1e-12; |d|u - c|| = that / (2r) = 1.25e-12,
// so 1e-10 has room), at the world point the map gives for its (element, xi),
// and in every element (the sphere r = 0.4 about the centre crosses all 8).
TEST(Teardrop, ParticlesOnTheMappedSphere) {
  const TeardropField f;
  HpParticleParams p;
  p.iso = f.iso();
  p.spacing = 0.15;
  p.progress = false;
  const HpParticleResult r = distribute_hp_particles(f, p);
  ASSERT_GT(r.positions.size(), 150u);
  std::set<int> elems;
  for (std::size_t i = 0; i < r.positions.size(); ++i) {
    const int e = r.element[i];
    elems.insert(e);
    const Vec3 u = f.global(e, r.xi[i]);
    EXPECT_LE(std::fabs(norm(u - f.params().centre) - f.params().radius), 1e-10) << i;
    EXPECT_EQ(r.positions[i], f.sample(e, r.xi[i]).x) << i;
    EXPECT_LE(norm(r.positions[i] - f.map(u)), 1e-14 * norm(f.domain().size())) << i;
    for (int a = 0; a < 3; ++a) EXPECT_LE(std::fabs(r.xi[i][a]), 1.0 + 1e-12);
  }
  EXPECT_EQ(elems.size(), 8u);
  EXPECT_TRUE(r.converged);
  EXPECT_GT(r.field_evaluations, 0u);
  EXPECT_GT(r.map_evaluations, 0u);
}

TEST(Teardrop, RefusesBadParameters) {
  TeardropParams p;
  p.spans = 0;
  EXPECT_THROW(TeardropField t(p), UsageError);
  p = {};
  p.radius = 0.5;
  EXPECT_THROW(TeardropField t(p), UsageError);
  p = {};
  p.taper = 1;
  EXPECT_THROW(TeardropField t(p), UsageError);
}

double power_sum(const Vec3& x, int k) { return std::pow(x.x, k) + std::pow(x.y, k) + std::pow(x.z, k); }

// The Modified_A coefficients reproduce x^8 + y^8 + z^8 (values of order 1,
// round-off of the 9-mode sums ~1e-15).
TEST(HexPower, EighthOrderExpansionIsExact) {
  const HexPowerScenario s = hex_power_field(8, {-1, -1, -1}, {1, 1, 1});
  const HpField f(s.mesh, s.field, "u");
  EXPECT_EQ(f.modes(0)[0], 9);
  for (const Vec3& x : {Vec3{0.1, -0.7, 0.95}, Vec3{-0.99, 0.5, 0.3}, Vec3{0.8, 0.8, -0.8}, Vec3{1, -1, 1}})
    EXPECT_NEAR(f.value(x), power_sum(x, 8), 1e-12) << x.x << " " << x.y << " " << x.z;
  EXPECT_THROW(hex_power_field(0, {0, 0, 0}, {1, 1, 1}), UsageError);
}

// Particles on x^8 + y^8 + z^8 = 1/2 in [-1,1]^3 (a rounded cube, flat
// faces and curvature up to ~10 at its edges): residual against the exact
// polynomial evaluated at the written world positions <= 1e-10.
TEST(HexPower, ParticlesOnTheEighthOrderLevelSet) {
  const HexPowerScenario s = hex_power_field(8, {-1, -1, -1}, {1, 1, 1});
  const HpField f(s.mesh, s.field, "u");
  HpParticleParams p;
  p.iso = 0.5;
  p.spacing = 0.2;
  p.progress = false;
  const HpParticleResult r = distribute_hp_particles(f, p);
  ASSERT_GT(r.positions.size(), 250u);
  double worst = 0;
  for (const Vec3& x : r.positions) worst = std::max(worst, std::fabs(power_sum(x, 8) - 0.5));
  EXPECT_LE(worst, 1e-10);
  // Every octant holds particles (the surface is symmetric).
  std::set<int> oct;
  for (const Vec3& x : r.positions) oct.insert((x.x > 0) + 2 * (x.y > 0) + 4 * (x.z > 0));
  EXPECT_EQ(oct.size(), 8u);
  EXPECT_TRUE(r.converged);
}

}  // namespace
}  // namespace pm
