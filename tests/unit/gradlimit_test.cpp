#include "pm/volume/gradlimit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "pm/base/error.h"

namespace pm {
namespace {

/// Largest face-neighbour slope |h(x) - h(y)| / spacing.
double face_slope(const Volume& h) {
  const Dims d = h.dims();
  double m = 0;
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      for (std::size_t i = 0; i < d.nx; ++i) {
        const double v = h.get(i, j, k);
        if (i + 1 < d.nx) m = std::max(m, std::fabs(h.get(i + 1, j, k) - v) / h.geometry().spacing(0));
        if (j + 1 < d.ny) m = std::max(m, std::fabs(h.get(i, j + 1, k) - v) / h.geometry().spacing(1));
        if (k + 1 < d.nz) m = std::max(m, std::fabs(h.get(i, j, k + 1) - v) / h.geometry().spacing(2));
      }
  return m;
}

/// Exact envelope min_y (h0(y) + delta |x - y|) over voxels with h0 > 0, by brute force.
std::vector<double> envelope(const Volume& h0, double delta) {
  std::vector<Vec3> pos;
  std::vector<double> val;
  const Dims d = h0.dims();
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      for (std::size_t i = 0; i < d.nx; ++i)
        if (h0.get(i, j, k) > 0) {
          pos.push_back(h0.geometry().index_to_world(Vec3(double(i), double(j), double(k))));
          val.push_back(h0.get(i, j, k));
        }
  std::vector<double> out(h0.count());
  for (std::size_t k = 0, v = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      for (std::size_t i = 0; i < d.nx; ++i, ++v) {
        const Vec3 x = h0.geometry().index_to_world(Vec3(double(i), double(j), double(k)));
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t s = 0; s < pos.size(); ++s) best = std::min(best, val[s] + delta * norm(x - pos[s]));
        out[v] = best;
      }
  return out;
}

/// A rough field: deterministic pseudo-random h0 in [0.2, 5].
Volume rough(Dims d, Geometry g) {
  Volume h(VoxelType::f32, d, g);
  std::uint32_t s = 12345;
  for (std::size_t i = 0; i < h.count(); ++i) {
    s = s * 1664525u + 1013904223u;
    h.set(i, 0.2 + 4.8 * double(s >> 8) / double(1u << 24));
  }
  return h;
}

TEST(GradLimit, RoughFieldBecomesLipschitzAndStaysBelowInput) {
  const double delta = 0.3;
  const Volume h0 = rough(Dims{14, 12, 10}, Geometry::with_spacing(1.0, 0.5, 2.0, Vec3(3, -1, 7)));
  const GradLimitResult r = gradient_limit(h0, {delta});
  EXPECT_EQ(r.h.type(), VoxelType::f32);
  EXPECT_LE(face_slope(r.h), delta * 1.01);
  EXPECT_LE(r.max_slope_ratio, 1.0 + 1e-6);  // exact up to float rounding
  EXPECT_GT(r.lowered, h0.count() / 2);
  const std::vector<double> exact = envelope(h0, delta);
  double worst = 0;
  for (std::size_t i = 0; i < h0.count(); ++i) {
    ASSERT_LE(r.h.get(i), h0.get(i)) << i;
    // An upper approximation of the exact envelope (float rounding aside)...
    ASSERT_GE(r.h.get(i), exact[i] * (1 - 1e-6)) << i;
    worst = std::max(worst, r.h.get(i) - exact[i]);
  }
  // ... and a close one: far less than delta times the smallest spacing.
  EXPECT_LT(worst, 0.1 * delta * 0.5);
}

TEST(GradLimit, LipschitzInputIsUnchanged) {
  Volume h0(VoxelType::f32, Dims{16, 5, 4}, Geometry::with_spacing(0.5, 1, 1, Vec3(-2, 0, 0)));
  for (std::size_t k = 0; k < 4; ++k)
    for (std::size_t j = 0; j < 5; ++j)
      for (std::size_t i = 0; i < 16; ++i) {
        const double x = h0.geometry().index_to_world(Vec3(double(i), double(j), double(k))).x;
        h0.set(i, j, k, 1 + 0.1 * x);
      }
  for (GradLimitMethod m : {GradLimitMethod::propagate, GradLimitMethod::upwind}) {
    GradLimitParams p;
    p.delta = 0.3;
    p.method = m;
    const GradLimitResult r = gradient_limit(h0, p);
    EXPECT_EQ(r.lowered, 0u);
    for (std::size_t i = 0; i < h0.count(); ++i) ASSERT_FLOAT_EQ(float(r.h.get(i)), float(h0.get(i)));
  }
}

TEST(GradLimit, SpikeBecomesACone) {
  // h = 10 except 1 at voxel c; anisotropic spacing (1, 2, 0.5).
  const double delta = 0.3;
  const Geometry g = Geometry::with_spacing(1.0, 2.0, 0.5);
  Volume h0(VoxelType::f64, Dims{21, 15, 31}, g);
  for (std::size_t i = 0; i < h0.count(); ++i) h0.set(i, 10.0);
  h0.set(10, 7, 15, 1.0);
  auto cone = [&](double i, double j, double k) {
    return std::min(10.0, 1 + delta * norm(g.directions * Vec3(i - 10, j - 7, k - 15)));
  };
  const GradLimitResult r = gradient_limit(h0, {delta});
  EXPECT_EQ(r.h.type(), VoxelType::f64);
  // One source: the propagation is exact (up to the float it stores h in).
  for (std::size_t k = 0; k < 31; ++k)
    for (std::size_t j = 0; j < 15; ++j)
      for (std::size_t i = 0; i < 21; ++i)
        ASSERT_NEAR(r.h.get(i, j, k), cone(double(i), double(j), double(k)), 1e-6) << i << " " << j << " " << k;
  EXPECT_NEAR(r.h.get(10, 10, 15), 1 + delta * 6, 1e-6);  // 3 voxels of 2 along y

  // Persson's upwind iteration: exact along the axes; elsewhere between the
  // Euclidean cone and the cone of the L1 (path along the axes) distance. A
  // first-order upwind scheme overestimates diagonal distances from a point
  // source most at the first diagonal step: (1,1,1) gets 1 + 1/sqrt2 + 1/sqrt3
  // = 2.284 instead of sqrt3 (ratio 1.32), less further out.
  GradLimitParams p;
  p.delta = delta;
  p.method = GradLimitMethod::upwind;
  const GradLimitResult u = gradient_limit(h0, p);
  EXPECT_LE(face_slope(u.h), delta * 1.01);
  EXPECT_NEAR(u.h.get(14, 7, 15), 1 + delta * 4, 1e-3);
  EXPECT_NEAR(u.h.get(10, 7, 9), 1 + delta * 3, 1e-3);
  for (auto [i, j, k] : {std::array<double, 3>{14, 9, 15}, {13, 9, 11}, {12, 8, 13}, {16, 7, 21}}) {
    const double e = cone(i, j, k), l1 = 1 + delta * (std::fabs(i - 10) * 1 + std::fabs(j - 7) * 2 + std::fabs(k - 15) * 0.5);
    const double v = u.h.get(std::size_t(i), std::size_t(j), std::size_t(k));
    EXPECT_GE(v, e - 1e-3);
    EXPECT_LE(v, std::min(10.0, l1) + 1e-3);
    EXPECT_LE(v - 1, 1.32 * (e - 1)) << i << " " << j << " " << k;
  }
}

TEST(GradLimit, UnknownVoxelsGetTheExtension) {
  const double delta = 0.5;
  Volume h0(VoxelType::f32, Dims{12, 10, 8}, Geometry::with_spacing(1, 1, 1.5));
  for (std::size_t k = 0; k < 8; ++k)
    for (std::size_t j = 0; j < 10; ++j)
      for (std::size_t i = 0; i < 12; ++i) h0.set(i, j, k, i < 3 ? 1.0 + 0.2 * double(j) : (i == 11 ? -1.0 : 0.0));
  h0.set(11, 9, 7, std::numeric_limits<double>::quiet_NaN());
  EXPECT_THROW(gradient_limit(h0, {delta}), InputError);
  GradLimitParams p;
  p.delta = delta;
  p.nonfinite_unknown = true;
  const GradLimitResult r = gradient_limit(h0, p);
  EXPECT_EQ(r.known, 3u * 10u * 8u);
  EXPECT_EQ(r.unknown, 9u * 10u * 8u);
  h0.set(11, 9, 7, 0.0);
  const std::vector<double> exact = envelope(h0, delta);
  for (std::size_t i = 0; i < h0.count(); ++i) {
    ASSERT_GT(r.h.get(i), 0.0);
    ASSERT_GE(r.h.get(i), exact[i] * (1 - 1e-6));
    ASSERT_LE(r.h.get(i), exact[i] + 0.02) << i;
  }
  EXPECT_LE(face_slope(r.h), delta * 1.01);
}

TEST(GradLimit, CeilingGivesTheCappedFieldForBothMethods) {
  // A few known voxels in a mostly unknown grid (as interior_sizing masks
  // a band around a surface): with a ceiling the propagation stops there,
  // and the result must still be min(h without a ceiling, ceiling).
  Volume h0(VoxelType::f32, Dims{40, 36, 30}, Geometry::with_spacing(1, 1.2, 0.8));
  const Volume r0 = rough(h0.dims(), h0.geometry());
  for (std::size_t v = 0; v < h0.count(); ++v) h0.set(v, v % 997 == 0 ? r0.get(v) : 0.0);
  for (GradLimitMethod m : {GradLimitMethod::propagate, GradLimitMethod::upwind}) {
    GradLimitParams p;
    p.delta = 0.2;
    p.method = m;
    const GradLimitResult free = gradient_limit(h0, p);
    p.ceiling = 2.0;
    const GradLimitResult capped = gradient_limit(h0, p);
    std::size_t at_ceiling = 0;
    for (std::size_t v = 0; v < h0.count(); ++v) {
      ASSERT_EQ(capped.h.get(v), std::min(free.h.get(v), 2.0)) << v;
      at_ceiling += capped.h.get(v) == 2.0;
    }
    EXPECT_GT(at_ceiling, h0.count() / 10);  // the ceiling did bind
    EXPECT_LT(at_ceiling, h0.count());
  }
  GradLimitParams bad;
  bad.ceiling = 0;
  EXPECT_THROW(gradient_limit(h0, bad), UsageError);
}

// flat_far_field caps at K + δ × 2 voxel diagonals, K the largest value a
// known voxel gets from limiting among the known voxels alone: every known
// voxel, and every voxel whose free value lies below the cap, comes out as
// without it; the rest sits at the cap; the slope bound holds everywhere.
// Two known slabs, one of them with an outlier far above what its
// neighbours allow: K lies between the largest free value of a known voxel
// and the largest known input, far below the latter.
TEST(GradLimit, FlatFarFieldKeepsEveryValueBelowTheCap) {
  Volume h0(VoxelType::f32, Dims{40, 36, 30}, Geometry::with_spacing(1, 1.2, 0.8));
  const Volume r0 = rough(h0.dims(), h0.geometry());
  double hmax = 0;
  for (std::size_t v = 0; v < h0.count(); ++v) {  // known in slabs at x < 4 and x >= 36 (bands near surfaces)
    h0.set(v, v % 40 < 4 || v % 40 >= 36 ? 0.2 * r0.get(v) : 0.0);
    hmax = std::max(hmax, h0.get(v));
  }
  const std::size_t outlier = h0.index(38, 18, 15);
  h0.set(outlier, 20 * hmax);
  GradLimitParams p;
  p.delta = 0.1;
  const GradLimitResult free = gradient_limit(h0, p);
  p.flat_far_field = true;
  const GradLimitResult flat = gradient_limit(h0, p);
  const double diag2 = 2 * p.delta * std::sqrt(1 + 1.2 * 1.2 + 0.8 * 0.8);
  double known_free = 0;
  for (std::size_t v = 0; v < h0.count(); ++v)
    if (h0.get(v) > 0) known_free = std::max(known_free, free.h.get(v));
  EXPECT_GE(flat.cap, known_free + diag2 - 1e-6);
  EXPECT_LE(flat.cap, hmax + p.delta * 1.2 + diag2);  // the outlier's neighbours pull it down
  std::size_t capped = 0;
  for (std::size_t v = 0; v < h0.count(); ++v) {
    if (h0.get(v) > 0) ASSERT_EQ(flat.h.get(v), free.h.get(v)) << v;
    ASSERT_EQ(flat.h.get(v), std::min(free.h.get(v), double(float(flat.cap)))) << v;
    capped += free.h.get(v) > flat.cap;
  }
  EXPECT_GT(capped, h0.count() / 10);  // the cap did bind
  EXPECT_LE(face_slope(flat.h), p.delta * 1.01);
}

TEST(GradLimit, BadInput) {
  Volume h0(VoxelType::f32, Dims{3, 3, 3});
  for (std::size_t i = 0; i < h0.count(); ++i) h0.set(i, 1.0);
  EXPECT_THROW(gradient_limit(h0, {0.0}), UsageError);
  EXPECT_THROW(gradient_limit(h0, {-0.3}), UsageError);
  GradLimitParams p;
  p.tolerance = 0;
  EXPECT_THROW(gradient_limit(h0, p), UsageError);
  EXPECT_THROW(gradient_limit(Volume(VoxelType::u8, Dims{3, 3, 3}), {}), InputError);
  Volume zero(VoxelType::f32, Dims{3, 3, 3});
  try {
    gradient_limit(zero, {});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no voxel has a finite h > 0"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pm
