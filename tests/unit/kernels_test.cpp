#include "pm/field/kernels.h"

#include <gtest/gtest.h>

#include <cmath>

namespace pm {
namespace {

constexpr KernelType kKernels[] = {KernelType::bspline, KernelType::catmull_rom};

// Fractions in [0,1) including the ends of the interval.
double fraction(int i, int n) { return double(i) / n; }

TEST(Kernels, PartitionOfUnityAndZeroSumDerivatives) {
  for (KernelType k : kKernels)
    for (int i = 0; i < 200; ++i) {
      const double u = fraction(i, 200);
      double w[4], d1[4], d2[4];
      kernel_weights(k, u, w, d1, d2);
      EXPECT_NEAR(w[0] + w[1] + w[2] + w[3], 1.0, 1e-15) << kernel_name(k) << " u=" << u;
      EXPECT_NEAR(d1[0] + d1[1] + d1[2] + d1[3], 0.0, 1e-15) << kernel_name(k) << " u=" << u;
      EXPECT_NEAR(d2[0] + d2[1] + d2[2] + d2[3], 0.0, 1e-14) << kernel_name(k) << " u=" << u;
    }
}

TEST(Kernels, WeightsAreTheKernelAtTheTapOffsets) {
  // w[q] = f(u + 1 - q): the weights and the piecewise kernel are written
  // independently, so this cross-checks both. Both are polynomials with
  // terms of magnitude <= ~5: rounding <= ~10 ulp(5) ~ 1e-14 in the worst case.
  for (KernelType k : kKernels)
    for (int i = 0; i < 100; ++i) {
      const double u = fraction(i, 100);
      double w[4], d1[4], d2[4];
      kernel_weights(k, u, w, d1, d2);
      for (int q = 0; q < 4; ++q) {
        const double x = u + 1 - q;
        EXPECT_NEAR(w[q], kernel_value(k, x), 1e-14) << kernel_name(k) << " x=" << x;
        EXPECT_NEAR(d1[q], kernel_d1(k, x), 1e-14) << kernel_name(k) << " x=" << x;
        // d2 jumps at integers for Catmull-Rom; u = 0 puts taps on them.
        if (k == KernelType::bspline || i > 0) {
          EXPECT_NEAR(d2[q], kernel_d2(k, x), 1e-14) << kernel_name(k) << " x=" << x;
        }
      }
    }
}

TEST(Kernels, LinearFunctionsReproducedExactly) {
  // Samples s_j = a j + b at taps j = -1..2 (relative to floor(t) = 0).
  const double a = 2.75, b = -1.5;
  for (KernelType k : kKernels)
    for (int i = 0; i < 100; ++i) {
      const double u = fraction(i, 100);
      double w[4], d1[4], d2[4];
      kernel_weights(k, u, w, d1, d2);
      double f = 0, f1 = 0, f2 = 0;
      for (int q = 0; q < 4; ++q) {
        const double s = a * (q - 1) + b;
        f += w[q] * s;
        f1 += d1[q] * s;
        f2 += d2[q] * s;
      }
      EXPECT_NEAR(f, a * u + b, 1e-14) << kernel_name(k);
      EXPECT_NEAR(f1, a, 1e-14) << kernel_name(k);
      EXPECT_NEAR(f2, 0.0, 1e-13) << kernel_name(k);
    }
}

TEST(Kernels, BsplineQuadraticsUpToTheVarianceOffset) {
  // The cubic B-spline has variance 1/3, so sum_j j² B(u - j) = u² + 1/3,
  // while its first and second derivatives are exactly 2u and 2.
  for (int i = 0; i < 100; ++i) {
    const double u = fraction(i, 100);
    double w[4], d1[4], d2[4];
    kernel_weights(KernelType::bspline, u, w, d1, d2);
    double f = 0, f1 = 0, f2 = 0;
    for (int q = 0; q < 4; ++q) {
      const double s = double(q - 1) * double(q - 1);
      f += w[q] * s;
      f1 += d1[q] * s;
      f2 += d2[q] * s;
    }
    EXPECT_NEAR(f, u * u + 1.0 / 3.0, 1e-14);
    EXPECT_NEAR(f1, 2 * u, 1e-14);
    EXPECT_NEAR(f2, 2.0, 1e-14);
  }
}

TEST(Kernels, CatmullRomInterpolatesSamples) {
  for (int n = -3; n <= 3; ++n) EXPECT_EQ(kernel_value(KernelType::catmull_rom, n), n == 0 ? 1.0 : 0.0);
  double w[4], d1[4], d2[4];
  kernel_weights(KernelType::catmull_rom, 0.0, w, d1, d2);
  EXPECT_EQ(w[0], 0.0);
  EXPECT_EQ(w[1], 1.0);
  EXPECT_EQ(w[2], 0.0);
  EXPECT_EQ(w[3], 0.0);
  // The B-spline does not interpolate: B(0) = 2/3, B(±1) = 1/6.
  EXPECT_NEAR(kernel_value(KernelType::bspline, 0), 2.0 / 3.0, 1e-15);
  EXPECT_NEAR(kernel_value(KernelType::bspline, 1), 1.0 / 6.0, 1e-15);
}

TEST(Kernels, DerivativesMatchCentralDifferences) {
  // Step h: truncation h²|f'''|/6 <= 3e-12 (|f'''| <= 9 for Catmull-Rom),
  // rounding ~1e-16/h = 1e-10; points within h of a knot are skipped since
  // f'' (and f''' ) jump there.
  const double h = 1e-6, tol = 1e-8;
  for (KernelType k : kKernels)
    for (int i = 0; i <= 440; ++i) {
      const double x = -2.2 + i * 0.01 + 0.00123;
      if (std::fabs(x - std::round(x)) < 2 * h) continue;
      const double fd1 = (kernel_value(k, x + h) - kernel_value(k, x - h)) / (2 * h);
      const double fd2 = (kernel_d1(k, x + h) - kernel_d1(k, x - h)) / (2 * h);
      EXPECT_NEAR(kernel_d1(k, x), fd1, tol) << kernel_name(k) << " x=" << x;
      EXPECT_NEAR(kernel_d2(k, x), fd2, tol) << kernel_name(k) << " x=" << x;
    }
}

TEST(Kernels, Continuity) {
  // Both are C1 at the knots; the B-spline is C2, Catmull-Rom's f'' jumps.
  const double e = 1e-9;
  for (KernelType k : kKernels)
    for (double knot : {-2.0, -1.0, 0.0, 1.0, 2.0}) {
      EXPECT_NEAR(kernel_value(k, knot - e), kernel_value(k, knot + e), 1e-8) << kernel_name(k);
      EXPECT_NEAR(kernel_d1(k, knot - e), kernel_d1(k, knot + e), 1e-7) << kernel_name(k);
    }
  for (double knot : {-2.0, -1.0, 0.0, 1.0, 2.0})
    EXPECT_NEAR(kernel_d2(KernelType::bspline, knot - e), kernel_d2(KernelType::bspline, knot + e), 1e-7);
  EXPECT_GT(std::fabs(kernel_d2(KernelType::catmull_rom, 1 - e) - kernel_d2(KernelType::catmull_rom, 1 + e)), 1.0);
  EXPECT_EQ(kernel_value(KernelType::bspline, 2.5), 0.0);
  EXPECT_EQ(kernel_d1(KernelType::catmull_rom, -2.0), 0.0);
}

}  // namespace
}  // namespace pm
