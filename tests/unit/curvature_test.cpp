#include "pm/field/curvature.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "pm/field/implicits.h"

namespace pm {
namespace {

void expect_frame(const Curvature& c, const Vec3& grad) {
  const Vec3 n = normalized(grad);
  EXPECT_NEAR(norm(c.normal - n), 0.0, 1e-14);
  EXPECT_NEAR(norm(c.dir1), 1.0, 1e-14);
  EXPECT_NEAR(norm(c.dir2), 1.0, 1e-14);
  EXPECT_NEAR(dot(c.dir1, n), 0.0, 1e-14);
  EXPECT_NEAR(dot(c.dir2, n), 0.0, 1e-14);
  EXPECT_NEAR(dot(c.dir1, c.dir2), 0.0, 1e-14);
  EXPECT_NEAR(norm(cross(c.dir1, c.dir2) - n), 0.0, 1e-14);  // right-handed
}

TEST(Curvature, AnalyticSphereIsOneOverR) {
  // Every level set of |x - c| - R is a sphere: at distance ρ from the centre
  // both curvatures are 1/ρ (1/R on the surface), positive for F < 0 inside.
  const auto f = make_implicit("sphere:r=2,cx=0.5,cy=-1,cz=3");
  std::mt19937 rng(1);
  std::normal_distribution<double> gauss;
  for (int n = 0; n < 50; ++n) {
    const Vec3 dir = normalized(Vec3(gauss(rng), gauss(rng), gauss(rng)));
    for (double rho : {2.0, 0.5, 7.0}) {
      const Vec3 x = Vec3(0.5, -1, 3) + dir * rho;
      Vec3 g;
      Mat3 h;
      f->evaluate(x, g, h);
      const Curvature c = curvature(g, h);
      EXPECT_NEAR(c.k1, 1 / rho, 1e-12);
      EXPECT_NEAR(c.k2, 1 / rho, 1e-12);
      EXPECT_NEAR(c.mean(), 1 / rho, 1e-12);
      EXPECT_NEAR(c.gaussian(), 1 / (rho * rho), 1e-12);
      EXPECT_NEAR(c.curvedness(), std::sqrt(2.0) / rho, 1e-12);
      expect_frame(c, g);  // umbilic: any orthonormal tangent pair
    }
  }
}

TEST(Curvature, TorusClosedForms) {
  // Torus R, r, point at tube angle v: κ_tube = 1/r along the tube circle,
  // κ_ring = cos v / (R + r cos v) along the ring; outer equator v = 0:
  // (1/r, 1/(R+r)), inner equator v = π: (1/r, -1/(R-r)), top v = π/2: (1/r, 0).
  const double R = 1.5, r = 0.5;
  const auto f = make_implicit("torus:R=1.5,r=0.5");
  for (double u : {0.0, 0.4, 2.5, -1.2})
    for (double v : {0.0, M_PI, M_PI / 2, 0.7, 2.2, -2.9}) {
      const Vec3 radial(std::cos(u), std::sin(u), 0);
      const Vec3 x = radial * (R + r * std::cos(v)) + Vec3(0, 0, r * std::sin(v));
      Vec3 g;
      Mat3 h;
      EXPECT_NEAR(f->evaluate(x, g, h), 0.0, 1e-14);
      const Curvature c = curvature(g, h);
      const double ring = std::cos(v) / (R + r * std::cos(v));
      EXPECT_NEAR(c.k1, 1 / r, 1e-12) << "u=" << u << " v=" << v;
      EXPECT_NEAR(c.k2, ring, 1e-12) << "u=" << u << " v=" << v;
      // dir2 follows the ring (horizontal, perpendicular to the radial plane),
      // dir1 the tube circle.
      const Vec3 ring_dir(-std::sin(u), std::cos(u), 0);
      EXPECT_NEAR(std::fabs(dot(c.dir2, ring_dir)), 1.0, 1e-9) << "u=" << u << " v=" << v;
      expect_frame(c, g);
    }
}

TEST(Curvature, CylinderAlongAnArbitraryAxis) {
  // F = |P_a (x - p)| - r for the unit axis a: gradient e (radial unit),
  // Hessian (I - a aᵀ - e eᵀ)/ρ. Expect (1/r, 0), dir2 along the axis.
  const double r = 0.8;
  const Vec3 axis = normalized(Vec3(0.3, -0.5, 0.8));
  const Vec3 p(1, 2, -1);
  std::mt19937 rng(4);
  std::normal_distribution<double> gauss;
  for (int n = 0; n < 20; ++n) {
    Vec3 w(gauss(rng), gauss(rng), gauss(rng));
    const Vec3 e = normalized(w - axis * dot(w, axis));
    const double rho = n % 2 ? r : 2.5 * r;  // on the surface and on an outer level set
    const Vec3 x = p + axis * gauss(rng) + e * rho;
    const Vec3 grad = normalized(x - p - axis * dot(x - p, axis));
    const Mat3 hess = (Mat3::identity() - outer(axis, axis) - outer(grad, grad)) * (1 / rho);
    for (double scale : {1.0, 3.7}) {  // F and 3.7 F have the same level sets
      const Curvature c = curvature(grad * scale, hess * scale);
      EXPECT_NEAR(c.k1, 1 / rho, 1e-12);
      EXPECT_NEAR(c.k2, 0.0, 1e-12);
      EXPECT_NEAR(std::fabs(dot(c.dir2, axis)), 1.0, 1e-12);
      EXPECT_NEAR(std::fabs(dot(c.dir1, axis)), 0.0, 1e-12);
      expect_frame(c, grad);
    }
  }
}

TEST(Curvature, ConcaveAndDegenerateCases) {
  // Inside-out sphere (F = R - |x|, F < 0 outside): curvatures -1/R.
  const double R = 2;
  const Vec3 n(0, 0, 1);
  const Mat3 h = (Mat3::identity() - outer(n, n)) * (1 / R);
  const Curvature c = curvature(-n, h * -1.0);
  EXPECT_NEAR(c.k1, -1 / R, 1e-15);
  EXPECT_NEAR(c.k2, -1 / R, 1e-15);
  // The Hessian's normal-normal part does not matter (G = P H P).
  Mat3 h2 = h;
  h2[2][2] = 17;
  EXPECT_NEAR(curvature(n, h2).k1, 1 / R, 1e-15);
  // Zero or non-finite gradient: zeros.
  const Curvature z = curvature(Vec3(), h);
  EXPECT_EQ(z.k1, 0.0);
  EXPECT_EQ(z.k2, 0.0);
  EXPECT_EQ(norm(z.normal), 0.0);
  EXPECT_EQ(curvature(Vec3(NAN, 0, 0), h).k1, 0.0);
}

}  // namespace
}  // namespace pm
