#include "pm/field/implicits.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "pm/base/error.h"

namespace pm {
namespace {

const char* kSpecs[] = {"sphere", "sphere:r=0.7,cx=0.3,cy=-1,cz=2", "torus", "torus:R=2,r=0.5",
                        "tangle", "tangle:s=0.5", "box", "box:a=1,b=2,c=0.5,r=0.3",
                        "twospheres", "twospheres:r=0.5,d=0.8"};

// True when x is within `m` of a set where the field is not smooth: the
// sphere centres, the torus core circle and axis, the box's q_i = 0 planes
// (the Hessian jumps there) and medial planes, the twospheres crease.
bool near_singular(const ScalarField& f, const Vec3& x, double m) {
  const std::string d = f.describe();
  double a = 1, b = 1, c = 1, r = 0.2, R = 1, cx = 0, cy = 0, cz = 0;
  if (std::sscanf(d.c_str(), "sphere r=%lf c=(%lf,%lf,%lf)", &r, &cx, &cy, &cz) == 4)
    return norm(x - Vec3(cx, cy, cz)) < m;
  if (std::sscanf(d.c_str(), "torus R=%lf r=%lf", &R, &r) == 2)
    return std::hypot(x.x, x.y) < m || std::hypot(std::hypot(x.x, x.y) - R, x.z) < m;
  if (std::sscanf(d.c_str(), "twospheres r=%lf d=%lf", &r, &c) == 2)
    return std::fabs(x.x) < m || norm(x - Vec3(c / 2, 0, 0)) < m || norm(x + Vec3(c / 2, 0, 0)) < m;
  if (std::sscanf(d.c_str(), "box a=%lf b=%lf c=%lf r=%lf", &a, &b, &c, &r) == 4) {
    double q[3] = {std::fabs(x.x) - (a - r), std::fabs(x.y) - (b - r), std::fabs(x.z) - (c - r)};
    for (double qi : q)
      if (std::fabs(qi) < m) return true;
    std::sort(q, q + 3);
    if (q[2] < 0 && q[2] - q[1] < m) return true;
    return std::fabs(x.x) < m || std::fabs(x.y) < m || std::fabs(x.z) < m;
  }
  return false;  // tangle: a polynomial
}

TEST(Implicits, DerivativesMatchCentralDifferences) {
  // δ = 1e-5, points at least m = 0.01 from the non-smooth sets. Truncation
  // (δ²/6)|F'''| resp. (δ²/6)|F''''| with |F^(k)| ~ k!/m^(k-1) for distances:
  // <= 2e-5 at worst, while |H| ~ 1/m there; rounding 1e-16 |F|/δ <= 1e-9
  // (tangle: |F| < 40). Tolerance 1e-6 · max(1, |H|).
  const double delta = 1e-5;
  std::mt19937 rng(42);
  for (const char* spec : kSpecs) {
    const auto f = make_implicit(spec);
    const Box dom = f->domain();
    std::uniform_real_distribution<double> ux(dom.lo.x, dom.hi.x), uy(dom.lo.y, dom.hi.y), uz(dom.lo.z, dom.hi.z);
    int tested = 0;
    for (int n = 0; n < 400; ++n) {
      const Vec3 x(ux(rng), uy(rng), uz(rng));
      if (near_singular(*f, x, 0.01)) continue;
      Vec3 grad;
      Mat3 hess;
      const double val = f->evaluate(x, grad, hess);
      Vec3 g2;
      EXPECT_DOUBLE_EQ(val, f->value(x)) << spec;
      EXPECT_DOUBLE_EQ(val, f->value_gradient(x, g2)) << spec;
      EXPECT_NEAR(norm(grad - g2), 0.0, 1e-15) << spec;
      double scale = 1;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) scale = std::max(scale, std::fabs(hess[r][c]));
      for (int a = 0; a < 3; ++a) {
        Vec3 e;
        e[a] = delta;
        EXPECT_NEAR(grad[a], (f->value(x + e) - f->value(x - e)) / (2 * delta), 1e-6 * scale)
            << spec << " at " << x.x << "," << x.y << "," << x.z;
        Vec3 gp, gm;
        f->value_gradient(x + e, gp);
        f->value_gradient(x - e, gm);
        for (int b = 0; b < 3; ++b)
          EXPECT_NEAR(hess[b][a], (gp[b] - gm[b]) / (2 * delta), 1e-6 * scale)
              << spec << " H" << b << a << " at " << x.x << "," << x.y << "," << x.z;
      }
      ++tested;
    }
    EXPECT_GT(tested, 300) << spec;
  }
}

TEST(Implicits, SurfaceStrictlyInsideDomain) {
  // F > 0 all over the domain's faces: the surface and the inside fit, with margin.
  for (const char* spec : kSpecs) {
    const auto f = make_implicit(spec);
    const Box b = f->domain();
    EXPECT_GT(f->resolution(), 0) << spec;
    EXPECT_LT(f->resolution(), 0.05 * norm(b.size())) << spec;
    double lowest = 1e300;
    for (int face = 0; face < 6; ++face)
      for (int i = 0; i <= 20; ++i)
        for (int j = 0; j <= 20; ++j) {
          const int a = face / 2;
          Vec3 x;
          x[a] = face % 2 ? b.hi[a] : b.lo[a];
          x[(a + 1) % 3] = b.lo[(a + 1) % 3] + b.size()[(a + 1) % 3] * i / 20;
          x[(a + 2) % 3] = b.lo[(a + 2) % 3] + b.size()[(a + 2) % 3] * j / 20;
          lowest = std::min(lowest, f->value(x));
        }
    EXPECT_GT(lowest, 0) << spec;
  }
}

TEST(Implicits, SphereAndTorusAreDistances) {
  const auto s = make_implicit("sphere:r=2,cx=1,cy=2,cz=3");
  EXPECT_DOUBLE_EQ(s->value(Vec3(6, 2, 3)), 3.0);
  EXPECT_NEAR(s->value(Vec3(1, 2.5, 3)), -1.5, 1e-15);
  EXPECT_DOUBLE_EQ(s->value(Vec3(1, 2, 3)), -2.0);
  EXPECT_NEAR(s->value(Vec3(1 + 2 / std::sqrt(3.0), 2 - 2 / std::sqrt(3.0), 3 + 2 / std::sqrt(3.0))), 0.0, 1e-15);

  const auto t = make_implicit("torus:R=1,r=0.4");
  EXPECT_NEAR(t->value(Vec3(3, 0, 0)), 1.6, 1e-15);
  EXPECT_NEAR(t->value(Vec3(0, 1.2, 0)), -0.2, 1e-15);
  EXPECT_NEAR(t->value(Vec3(0, 0, 0)), 0.6, 1e-15);
  EXPECT_NEAR(t->value(Vec3(0, 0, 2)), std::sqrt(5.0) - 0.4, 1e-15);
  // Brute force: distance to a dense sampling of the surface. Nearest-sample
  // error <= (gap²/8)/|F| with gap ~ 2π·1.4/1500: ~5e-5 at |F| >= 0.1.
  const int nu = 1500, nv = 600;
  for (const Vec3& x : {Vec3(0.3, -0.9, 0.5), Vec3(-1.5, 0.4, -0.3), Vec3(0.2, 0.9, 0.2), Vec3(0.6, 0.6, 0.9)}) {
    double best = 1e300;
    for (int i = 0; i < nu; ++i) {
      const double u = 2 * M_PI * i / nu;
      for (int j = 0; j < nv; ++j) {
        const double v = 2 * M_PI * j / nv;
        const Vec3 p((1 + 0.4 * std::cos(v)) * std::cos(u), (1 + 0.4 * std::cos(v)) * std::sin(u), 0.4 * std::sin(v));
        best = std::min(best, norm2(x - p));
      }
    }
    EXPECT_NEAR(std::fabs(t->value(x)), std::sqrt(best), 2e-4);
  }
}

TEST(Implicits, BoxIsZeroOnFacesAndMinusDistanceInside) {
  const double a = 1, b = 2, c = 3, r = 0.2;
  const auto f = make_implicit("box:a=1,b=2,c=3,r=0.2");
  // Flat parts of the faces.
  EXPECT_NEAR(f->value(Vec3(1, 0.3, -1.2)), 0.0, 1e-15);
  EXPECT_NEAR(f->value(Vec3(-0.5, -2, 2.7)), 0.0, 1e-15);
  EXPECT_NEAR(f->value(Vec3(0.1, 1.7, 3)), 0.0, 1e-15);
  // Rounded edge and corner.
  for (double th : {0.1, 0.7, 1.3}) {
    EXPECT_NEAR(f->value(Vec3(a - r + r * std::cos(th), -(b - r + r * std::sin(th)), 0.5)), 0.0, 1e-15);
    EXPECT_NEAR(f->value(Vec3(a - r + r * std::cos(th) * 0.6, b - r + r * std::sin(th) * 0.6, -(c - r + 0.8 * r))), 0.0, 1e-15);
  }
  // Inside: minus the distance to the nearest face.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> ux(-a + r, a - r), uy(-b + r, b - r), uz(-c + r, c - r);
  for (int n = 0; n < 100; ++n) {
    const Vec3 x(ux(rng), uy(rng), uz(rng));
    const double dmin = std::min({a - std::fabs(x.x), b - std::fabs(x.y), c - std::fabs(x.z)});
    EXPECT_NEAR(f->value(x), -dmin, 1e-15);
  }
  // Outside: distance to a face, to a rounded edge (circle centre (0.8,1.8)),
  // to a rounded corner (sphere centre (0.8,1.8,2.8)).
  EXPECT_DOUBLE_EQ(f->value(Vec3(2, 0, 0)), 1.0);
  EXPECT_NEAR(f->value(Vec3(1.8, 2.8, 0)), std::sqrt(2.0) - r, 1e-15);
  EXPECT_NEAR(f->value(Vec3(1.8, 2.8, 3.8)), std::sqrt(3.0) - r, 1e-15);
  EXPECT_NEAR(f->value(Vec3(0.9, 1.9, 0)), std::sqrt(0.02) - r, 1e-15);  // inside, near an edge
  // Hessian: 0 over a face, the edge-distance Hessian near an edge.
  Vec3 g;
  Mat3 h;
  f->evaluate(Vec3(1.5, 0.2, 0.1), g, h);
  EXPECT_EQ(g, Vec3(1, 0, 0));
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_EQ(h[i][j], 0.0);
  f->evaluate(Vec3(1.8, 2.8, 0), g, h);  // distance sqrt(2) from the edge line
  EXPECT_NEAR(h[0][0], 0.5 / std::sqrt(2.0), 1e-15);
  EXPECT_NEAR(h[0][1], -0.5 / std::sqrt(2.0), 1e-15);
  EXPECT_EQ(h[2][2], 0.0);
}

TEST(Implicits, TwoSpheresIsTheMinimumWithACrease) {
  const auto f = make_implicit("twospheres:r=1,d=1.2");
  EXPECT_NEAR(f->value(Vec3(-1.6, 0, 0)), 0.0, 1e-15);
  EXPECT_NEAR(f->value(Vec3(1.6, 0, 0)), 0.0, 1e-15);
  EXPECT_NEAR(f->value(Vec3(0, 0, 0)), -0.4, 1e-15);
  EXPECT_NEAR(f->value(Vec3(0, 0.8, 0)), 0.0, 1e-15);  // on the crease circle
  Vec3 gl, gr;
  f->value_gradient(Vec3(-1e-9, 0.8, 0), gl);
  f->value_gradient(Vec3(1e-9, 0.8, 0), gr);
  EXPECT_NEAR(gl.x, 0.6, 1e-6);  // normals of the two spheres: the crease is sharp
  EXPECT_NEAR(gr.x, -0.6, 1e-6);
}

TEST(Implicits, TangleValues) {
  const auto f = make_implicit("tangle");
  EXPECT_DOUBLE_EQ(f->value(Vec3(0, 0, 0)), 11.8);
  EXPECT_NEAR(f->value(Vec3(1, 2, -1)), 1 - 5 + 16 - 20 + 1 - 5 + 11.8, 1e-13);
  const auto g = make_implicit("tangle:s=2");
  EXPECT_DOUBLE_EQ(g->value(Vec3(2, 4, -2)), f->value(Vec3(1, 2, -1)));
  EXPECT_LT(f->value(Vec3(1.58, 1.58, 1.58)), 0);  // inside a corner blob
}

void expect_usage_error(const std::string& spec, const std::string& needle) {
  try {
    make_implicit(spec);
    ADD_FAILURE() << "no UsageError for " << spec;
  } catch (const UsageError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(needle), std::string::npos) << spec << " -> " << m;
    EXPECT_NE(m.find(quote(spec)), std::string::npos) << spec << " -> " << m;
  }
}

TEST(Implicits, BadSpecsThrowUsageError) {
  expect_usage_error("cube", "sphere, torus, tangle, box, twospheres");
  expect_usage_error("", "expected one of");
  expect_usage_error("Sphere", "expected one of");
  expect_usage_error("sphere:q=1", "r, cx, cy, cz");
  expect_usage_error("torus:R=1,rr=0.2", "R, r");
  expect_usage_error("sphere:r=0", "r must be > 0, got 0");
  expect_usage_error("sphere:r=-1", "r must be > 0, got -1");
  expect_usage_error("box:a=-1", "a must be > 0");
  expect_usage_error("sphere:r=abc", "not a number");
  expect_usage_error("sphere:r=1x", "not a number");
  expect_usage_error("sphere:r", "not a number");
  expect_usage_error("sphere:r=nan", "not a number");
  expect_usage_error("tangle:s=inf", "not a number");
  expect_usage_error("sphere:r=1,r=2", "given twice");
  expect_usage_error("torus:R=1,r=1.5", "must be < ring radius");
  expect_usage_error("box:r=2", "smallest half-extent");
  expect_usage_error("twospheres:", "unknown parameter");
  EXPECT_NO_THROW(make_implicit("sphere:cx=-3.5"));  // centres may be negative
}

TEST(Implicits, HelpAndDescriptions) {
  const std::string help = implicit_help();
  for (const char* n : {"sphere[:r=1,cx=0,cy=0,cz=0]", "torus[:R=1,r=0.4]", "tangle[:s=1]",
                        "box[:a=1,b=1,c=1,r=0.2]", "twospheres[:r=1,d=1.2]"})
    EXPECT_NE(help.find(n), std::string::npos) << n << " missing in\n" << help;
  EXPECT_EQ(make_implicit("sphere:r=2")->describe(), "sphere r=2 c=(0,0,0)");
  EXPECT_EQ(make_implicit("torus")->describe(), "torus R=1 r=0.4");
  EXPECT_EQ(make_implicit("box:c=3")->describe(), "box a=1 b=1 c=3 r=0.2");
  EXPECT_EQ(make_implicit("twospheres")->describe(), "twospheres r=1 d=1.2");
  EXPECT_EQ(make_implicit("tangle")->describe(), "tangle s=1");
}

}  // namespace
}  // namespace pm
