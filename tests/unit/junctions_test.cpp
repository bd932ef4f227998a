#include "pm/field/junctions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <random>

#include "pm/base/error.h"
#include "pm/base/volume.h"
#include "analytic_materials.h"

namespace pm {
namespace {

using test::AnalyticField;
using test::four_tetrahedral;
using test::three_wedges;
using test::two_spheres;

// --- smooth max ------------------------------------------------------------------

TEST(SmoothMax, StepIsC2AndCompact) {
  const double w = 0.01;
  EXPECT_EQ(smooth_step(-w, w), 0.0);
  EXPECT_EQ(smooth_step(-2 * w, w), 0.0);
  EXPECT_EQ(smooth_step(w, w), 2.0);
  EXPECT_DOUBLE_EQ(smooth_step(0, w), 1.0);
  for (double z = -1.2 * w; z <= 1.2 * w; z += w / 37) {
    double d = 0;
    smooth_step(z, w, &d);
    const double e = 1e-7 * w;
    const double fd = (smooth_step(z + e, w) - smooth_step(z - e, w)) / (2 * e);
    EXPECT_NEAR(d, fd, 1e-5 / w) << z;
    EXPECT_NEAR(smooth_step(z, w) + smooth_step(-z, w), 2.0, 1e-14);  // odd around 1
  }
}

TEST(SmoothMax, ExactOnTiesAndAwayFromThem) {
  const double w = 1e-3;
  const double a[] = {0.7, 0.2, -1.0};
  EXPECT_EQ(smooth_max(a, 3, w), 0.7);
  const double b[] = {0.7, 0.7, 0.1};
  EXPECT_DOUBLE_EQ(smooth_max(b, 3, w), 0.7);
  const double c[] = {0.3, 0.3, 0.3, 0.3};
  EXPECT_DOUBLE_EQ(smooth_max(c, 4, w), 0.3);
  // Inside the band it is a convex combination: between the mean and the max.
  const double d[] = {0.5, 0.5 - 0.3 * w};
  const double s = smooth_max(d, 2, w);
  EXPECT_LT(s, 0.5);
  EXPECT_GT(s, 0.5 - 0.3 * w);
}

TEST(SmoothMax, GradientMatchesFiniteDifferences) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  const double w = 0.05;
  for (int trial = 0; trial < 200; ++trial) {
    double z[4];
    for (double& v : z) v = 0.03 * u(rng);  // many values inside each other's band
    double dz[4];
    smooth_max(z, 4, w, dz);
    double sum = 0;
    for (int k = 0; k < 4; ++k) {
      double zp[4], zm[4];
      std::copy(z, z + 4, zp);
      std::copy(z, z + 4, zm);
      const double e = 1e-7;
      zp[k] += e;
      zm[k] -= e;
      const double fd = (smooth_max(zp, 4, w) - smooth_max(zm, 4, w)) / (2 * e);
      EXPECT_NEAR(dz[k], fd, 1e-6) << trial << " " << k;
      sum += dz[k];
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);  // translation invariance
  }
}

// SPEC §6's reconstructed smooth max (sigmoid g, tie-count normalisation) is
// not exact when one value leads by d: it returns max - d η/2 with
// η = 1 - d/sqrt(d² + ε). At a 2-junction with a third material at
// distance d in f, both IO functions are then positive: J never vanishes.
TEST(SmoothMax, SpecReconstructionIsNotExactOffTies) {
  const double eps = 1e-5, d = 0.01;
  const double z[] = {1.0, 1.0 - d};
  const double eta = 1 - d / std::sqrt(d * d + eps);
  EXPECT_NEAR(smooth_max_spec(z, 2, eps), 1.0 - d * eta / 2, 1e-12);
  EXPECT_GT(1.0 - smooth_max_spec(z, 2, eps), 1e-4);
  // ...while it is exact on exact ties, as SPEC says.
  const double t[] = {0.4, 0.4, 0.4};
  EXPECT_NEAR(smooth_max_spec(t, 3, eps), 0.4, 1e-15);
  // The compact smooth max is exact for the same input once d >= w.
  EXPECT_EQ(smooth_max(z, 2, 3e-3), 1.0);

  // f_a = f_b = 1, f_c = 1 - d: with SPEC's smooth max f̃_a = f̃_b > 0.
  const double fa = 1.0, fb = 1.0, fc = 1.0 - d;
  const double za[] = {fb, fc}, zb[] = {fa, fc};
  const double io_a = fa - smooth_max_spec(za, 2, eps), io_b = fb - smooth_max_spec(zb, 2, eps);
  EXPECT_GT(io_a * io_a + io_b * io_b, 1e-9);
  const double io_a2 = fa - smooth_max(za, 2, 3e-3), io_b2 = fb - smooth_max(zb, 2, 3e-3);
  EXPECT_EQ(io_a2 * io_a2 + io_b2 * io_b2, 0.0);
}

// --- cell indicators on analytic material sets -----------------------------------

// Three 120° wedges around the z axis: f_i = n_i·(x, y) + c_i |(x,y)|²
// (curved interfaces when c differs), material i where f_i is largest.
TEST(CellIndicator, ZeroOnJunctionPositiveOff) {
  const MaterialSet m = three_wedges(0.0);
  IndicatorSample s;
  const JunctionCell c01 = make_cell({0, 1}), c012 = make_cell({0, 1, 2});
  // Interface 0|1 is the ray bisecting n_0 and n_1 (angle 150°).
  const double ang = 150.0 * M_PI / 180.0;
  const Vec3 dir{std::cos(ang), std::sin(ang), 0};
  for (double r : {0.05, 0.2, 0.5, 0.9}) {
    for (double z : {-0.5, 0.0, 0.7}) {
      const Vec3 p = dir * r + Vec3{0, 0, z};
      sample_indicators(m, p, s);
      EXPECT_LT(cell_indicator(s, c01, kSmoothMaxWidth), 1e-26) << r;
      // Off the interface by δ along its normal: J ≈ 2 (|∇f_0 - ∇f_1| δ)² = 2 (√3 δ)².
      const Vec3 nrm{-dir.y, dir.x, 0};
      for (double delta : {1e-3, 1e-2}) {
        sample_indicators(m, p + nrm * delta, s);
        const double j = cell_indicator(s, c01, kSmoothMaxWidth);
        EXPECT_NEAR(j, 2 * 3 * delta * delta, 0.05 * 6 * delta * delta) << r << " " << delta;
      }
      // The 1-cell indicator is positive there (not on the triple line).
      sample_indicators(m, p, s);
      EXPECT_GT(cell_indicator(s, c012, kSmoothMaxWidth), 0.5 * r * r);
    }
  }
  // On the triple line every indicator of the three materials vanishes.
  for (double z : {-0.8, 0.0, 0.3}) {
    sample_indicators(m, {0, 0, z}, s);
    EXPECT_LT(cell_indicator(s, c012, kSmoothMaxWidth), 1e-28);
    EXPECT_LT(cell_indicator(s, c01, kSmoothMaxWidth), 1e-28);
  }
  // Random points: J >= 0, and J_012 = 0 only on the axis.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int t = 0; t < 500; ++t) {
    const Vec3 p{u(rng), u(rng), u(rng)};
    sample_indicators(m, p, s);
    const double rho = std::hypot(p.x, p.y);
    EXPECT_GE(cell_indicator(s, c01, kSmoothMaxWidth), 0.0);
    EXPECT_GT(cell_indicator(s, c012, kSmoothMaxWidth), 0.25 * rho * rho * 0.5);
  }
}

TEST(CellIndicator, QuadrupleJunctionOfFourCones) {
  const MaterialSet m = four_tetrahedral();
  IndicatorSample s;
  const JunctionCell q = make_cell({0, 1, 2, 3});
  sample_indicators(m, {0, 0, 0}, s);
  EXPECT_LT(cell_indicator(s, q), 1e-28);
  // Along the triple ray of materials 0,1,2 (direction -n_3) J_012 = 0, J_0123 > 0.
  const JunctionCell t = make_cell({0, 1, 2});
  const Vec3 dir = -test::tetra_direction(3);
  for (double r : {0.1, 0.4}) {
    sample_indicators(m, dir * r, s);
    EXPECT_LT(cell_indicator(s, t), 1e-26);
    EXPECT_GT(cell_indicator(s, q), 0.1 * r * r);
  }
}

TEST(CellIndicator, GradientMatchesFiniteDifferences) {
  const MaterialSet m = three_wedges(0.4);
  IndicatorSample s;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  const JunctionCell cells[] = {make_cell({0, 1}), make_cell({1, 2}), make_cell({0, 1, 2})};
  for (int t = 0; t < 100; ++t) {
    const Vec3 p{u(rng), u(rng), u(rng)};
    for (const JunctionCell& c : cells) {
      sample_indicators(m, p, s);
      Vec3 g;
      cell_indicator(s, c, 0.05, &g);
      for (int a = 0; a < 3; ++a) {
        Vec3 pp = p, pm = p;
        const double e = 1e-6;
        pp[a] += e;
        pm[a] -= e;
        sample_indicators(m, pp, s);
        const double jp = cell_indicator(s, c, 0.05);
        sample_indicators(m, pm, s);
        const double jm = cell_indicator(s, c, 0.05);
        EXPECT_NEAR(g[a], (jp - jm) / (2 * e), 1e-5 * (1 + std::fabs(g[a]))) << t << " axis " << a;
      }
    }
  }
}

// --- tangent projection -----------------------------------------------------------

TEST(TangentProjection, CurveTangentIsTheAxisAndSurfaceNormalIsRemoved) {
  const MaterialSet m = three_wedges(0.0);
  IndicatorSample s;
  sample_indicators(m, {0, 0, 0.2}, s);
  std::array<Vec3, 4> n;
  for (int k = 0; k < 3; ++k) {
    Vec3 g;
    io_function(s, std::size_t(k), kSmoothMaxWidth, &g);
    n[std::size_t(k)] = normalized(g);
  }
  const Vec3 v{0.3, -0.7, 0.5};
  const Vec3 pt = project_to_tangent(make_cell({0, 1, 2}), n, v);
  EXPECT_NEAR(pt.x, 0, 1e-12);
  EXPECT_NEAR(pt.y, 0, 1e-12);
  EXPECT_NEAR(pt.z, 0.5, 1e-12);
  // 2-cell 0|1 on its ray: the result is orthogonal to the interface normal.
  const double ang = 150.0 * M_PI / 180.0;
  sample_indicators(m, Vec3{std::cos(ang), std::sin(ang), 0} * 0.5, s);
  for (int k = 0; k < 2; ++k) {
    Vec3 g;
    io_function(s, std::size_t(k), kSmoothMaxWidth, &g);
    n[std::size_t(k)] = normalized(g);
  }
  const Vec3 ps = project_to_tangent(make_cell({0, 1}), n, v);
  const Vec3 nrm{-std::sin(ang), std::cos(ang), 0};
  EXPECT_NEAR(dot(ps, nrm), 0, 1e-12);
  EXPECT_NEAR(norm(ps - (v - nrm * dot(v, nrm))), 0, 1e-12);
  EXPECT_EQ(norm(project_to_tangent(make_cell({0, 1, 2, 3}), n, v)), 0.0);
}

// --- re-projection ----------------------------------------------------------------

TEST(ProjectToCell, TripleLineOfCurvedWedges) {
  const MaterialSet m = three_wedges(0.4);  // curved interfaces; the triple line is still the z axis
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  const JunctionCell c = make_cell({0, 1, 2});
  int worst = 0;
  // Residual <= tol in f means a distance <= sqrt(2) tol / σ_min(R) to the
  // line, R = rows ∇(f_0 - f_1), ∇(f_1 - f_2); σ_min ≈ 1.2 here: tol 1e-7
  // keeps every point within 1e-6 of the axis.
  CellProjectParams pp;
  pp.tolerance = 1e-7;
  for (int t = 0; t < 200; ++t) {
    const Vec3 p{u(rng), u(rng), u(rng)};
    const CellProjection r = project_to_cell(m, c, p, pp);
    ASSERT_TRUE(r.converged) << t;
    EXPECT_TRUE(r.dominant);
    EXPECT_LT(std::hypot(r.x.x, r.x.y), 1e-6) << t;
    EXPECT_NEAR(std::fabs(r.frame.z), 1.0, 1e-9);
    worst = std::max(worst, r.steps);
  }
  EXPECT_LE(worst, 8);  // quadratic convergence from 0.3 away
}

TEST(ProjectToCell, ValueBoundsSkipFarMaterialsWithTheSameResult) {
  // A label map: background 0, a slab 1 (x < 10) and a cube 2 far from the
  // slab's face; projections onto the 0-1 interface must give the same
  // result with the bounds, most of them without evaluating material 2.
  Volume lab(VoxelType::u8, Dims{32, 28, 30}, Geometry::with_spacing(0.5, 0.6, 0.55, Vec3(-3, 1, 2)));
  for (std::size_t k = 0; k < 30; ++k)
    for (std::size_t j = 0; j < 28; ++j)
      for (std::size_t i = 0; i < 32; ++i) {
        int l = i < 10 && j > 2 && j < 25 && k > 2 && k < 27 ? 1 : 0;
        if (i >= 22 && i <= 27 && j >= 10 && j <= 16 && k >= 12 && k <= 18) l = 2;
        lab.set(i, j, k, l);
      }
  const MaterialSet m = materials_from_labels(lab);
  ASSERT_EQ(m.size(), 3u);
  const auto bounds = material_bounds(m);
  ASSERT_EQ(bounds.size(), 3u);
  const Geometry& g = lab.geometry();
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(0, 1);
  std::size_t bounded = 0, evals_with = 0, evals_without = 0, dominant = 0;
  for (int t = 0; t < 400; ++t) {
    const Vec3 p = g.index_to_world(Vec3(7 + 5 * u(rng), 4 + 19 * u(rng), 4 + 21 * u(rng)));
    CellProjectParams with;
    with.bounds = &bounds;
    const CellProjection a = project_to_cell(m, make_cell({0, 1}), p);
    const CellProjection b = project_to_cell(m, make_cell({0, 1}), p, with);
    ASSERT_EQ(a.converged, b.converged);
    ASSERT_EQ(a.dominant, b.dominant);
    ASSERT_EQ(a.x, b.x);
    ASSERT_EQ(a.steps, b.steps);
    bounded += b.bounded;
    evals_with += b.evaluations;
    evals_without += a.evaluations;
    dominant += a.dominant;
  }
  EXPECT_GT(dominant, 300u);
  EXPECT_GT(bounded, 300u);  // the cube lies 6 mm from the slab's face
  EXPECT_EQ(evals_without - evals_with, bounded);
}

TEST(ProjectToCell, QuadruplePointAndSurfaces) {
  const MaterialSet m = four_tetrahedral();
  const CellProjection q = project_to_cell(m, make_cell({0, 1, 2, 3}), {0.2, -0.1, 0.15});
  ASSERT_TRUE(q.converged);
  EXPECT_LT(norm(q.x), 1e-9);  // linear fields: exact after one step
  EXPECT_LE(q.steps, 2);
  EXPECT_EQ(norm(q.frame), 0.0);
}

TEST(ProjectToCell, TwoSpheresInABox) {
  // Background 0, sphere 1 (centre -0.3, r 0.5), sphere 2 (centre +0.3, r 0.4).
  const MaterialSet m = two_spheres();
  const Vec3 c1{-0.3, 0, 0}, c2{0.3, 0, 0};
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> u(-1, 1);
  int on01 = 0;
  for (int t = 0; t < 300; ++t) {
    const Vec3 p{u(rng) * 0.9, u(rng) * 0.7, u(rng) * 0.7};
    const CellProjection r = project_to_cell(m, make_cell({0, 1}), p);
    if (!r.converged || !r.dominant) continue;
    ++on01;
    EXPECT_NEAR(norm(r.x - c1), 0.5, 1e-6);
    EXPECT_GT(norm(r.x - c2), 0.4 - 1e-6);  // not inside sphere 2
    // The frame points from background (a = 0) into sphere 1 (b = 1): inwards.
    EXPECT_NEAR(dot(r.frame, normalized(c1 - r.x)), 1.0, 1e-6);
  }
  EXPECT_GT(on01, 100);
  // Triple circle: |x - c1| = 0.5 and |x - c2| = 0.4 (both f = 0 = background).
  for (int t = 0; t < 50; ++t) {
    const double th = M_PI * u(rng), rad = 0.33 + 0.1 * u(rng);
    const Vec3 p{0.075 + 0.1 * u(rng), rad * std::cos(th), rad * std::sin(th)};
    const CellProjection r = project_to_cell(m, make_cell({0, 1, 2}), p);
    ASSERT_TRUE(r.converged) << t;
    EXPECT_NEAR(norm(r.x - c1), 0.5, 1e-6);
    EXPECT_NEAR(norm(r.x - c2), 0.4, 1e-6);
  }
}

TEST(ProjectToCell, HiddenInterfaceIsNotDominant) {
  // The plane f_0 = f_1 continues into material 2's wedge, where material 2
  // is on top: projecting there converges but is not a junction.
  const MaterialSet m = three_wedges(0.0);
  const double ang = -30.0 * M_PI / 180.0;  // deep inside wedge 2 (n_2 at 330°), on the extension of 0|1
  const CellProjection r = project_to_cell(m, make_cell({0, 1}), Vec3{std::cos(ang), std::sin(ang), 0} * 0.5);
  EXPECT_TRUE(r.converged);
  EXPECT_FALSE(r.dominant);
}

TEST(JunctionCell, MakeCellChecks) {
  EXPECT_THROW(make_cell({1}), UsageError);
  EXPECT_THROW(make_cell({1, 1}), UsageError);
  EXPECT_THROW(make_cell({0, 1, 2, 3, 4}), UsageError);
  const JunctionCell c = make_cell({3, 1, 2});
  EXPECT_EQ(c.m[0], 1);
  EXPECT_EQ(c.dimension(), 1);
  EXPECT_TRUE(make_cell({0, 1, 2, 3}).contains_all(c));
  EXPECT_FALSE(c.contains_all(make_cell({0, 1})));
}

}  // namespace
}  // namespace pm
