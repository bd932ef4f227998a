#include "pm/field/volume_field.h"

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "pm/base/error.h"
#include "pm/field/curvature.h"
#include "pm/field/implicits.h"

namespace pm {
namespace {

// An anisotropic, non-orthogonal (sheared and rotated) geometry.
Geometry oblique_geometry() {
  Geometry g;
  g.origin = Vec3(-1.25, 0.5, 2.0);
  g.directions = Mat3::from_columns(Vec3(0.7, 0.1, 0.0), Vec3(-0.2, 0.9, 0.15), Vec3(0.05, -0.1, 1.3));
  return g;
}

template <class F>
Volume sample(Dims d, const Geometry& g, F f) {
  Volume v(VoxelType::f32, d, g);
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      for (std::size_t i = 0; i < d.nx; ++i) v.set(i, j, k, f(g.index_to_world(Vec3(i, j, k))));
  return v;
}

Volume random_volume(Dims d, const Geometry& g, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  return sample(d, g, [&](const Vec3&) { return u(rng); });
}

// Random index-space positions with fractional parts in [0.05, 0.95] (so a
// world step of 1e-5 stays inside one cell, where the field is a tricubic
// polynomial), covering border cells too.
std::vector<Vec3> cell_interior_points(const Volume& v, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> frac(0.05, 0.95);
  std::vector<Vec3> pts;
  for (int n = 0; n < count; ++n) {
    Vec3 t;
    for (int a = 0; a < 3; ++a) {
      std::uniform_int_distribution<int> cell(0, int(v.dims()[a]) - 2);
      t[a] = cell(rng) + frac(rng);
    }
    pts.push_back(v.geometry().index_to_world(t));
  }
  return pts;
}

const VolumeFieldParams kBspline{KernelType::bspline, KernelType::bspline};
const VolumeFieldParams kCatmullRom{KernelType::catmull_rom, KernelType::catmull_rom};

TEST(VolumeField, DeltaVolumeGivesKernelProducts) {
  // One non-zero voxel: F(x) = 2.5 f(tx - 5) f(ty - 4) f(tz - 6) with
  // t = (x - origin) / spacing per axis. Checks the storage layout and that
  // each axis gets its own weights and spacing.
  const Geometry g = Geometry::with_spacing(0.5, 0.8, 1.25, Vec3(1, -2, 3));
  Volume v(VoxelType::f32, Dims{11, 9, 13}, g);
  v.set(5, 4, 6, 2.5);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> off(-2.2, 2.2);
  for (const VolumeFieldParams& p : {kBspline, kCatmullRom, VolumeFieldParams::chapter5_mix()}) {
    const VolumeField f(v, p);
    const KernelType kv = p.value_kernel, kd = p.deriv_kernel;
    for (int n = 0; n < 200; ++n) {
      const double a = off(rng), b = off(rng), c = off(rng);
      const Vec3 x = g.index_to_world(Vec3(5 + a, 4 + b, 6 + c));
      Vec3 grad;
      Mat3 hess;
      const double val = f.evaluate(x, grad, hess);
      EXPECT_NEAR(val, 2.5 * kernel_value(kv, a) * kernel_value(kv, b) * kernel_value(kv, c), 1e-12);
      const double wa = kernel_value(kd, a), wb = kernel_value(kd, b), wc = kernel_value(kd, c);
      const double da = kernel_d1(kd, a), db = kernel_d1(kd, b), dc = kernel_d1(kd, c);
      EXPECT_NEAR(grad.x, 2.5 * da * wb * wc / 0.5, 1e-12);
      EXPECT_NEAR(grad.y, 2.5 * wa * db * wc / 0.8, 1e-12);
      EXPECT_NEAR(grad.z, 2.5 * wa * wb * dc / 1.25, 1e-12);
      EXPECT_NEAR(hess[0][1], 2.5 * da * db * wc / (0.5 * 0.8), 1e-12);
      EXPECT_NEAR(hess[1][2], 2.5 * wa * db * dc / (0.8 * 1.25), 1e-12);
      EXPECT_NEAR(hess[0][2], 2.5 * da * wb * dc / (0.5 * 1.25), 1e-12);
      // Second derivatives jump at knots for Catmull-Rom; compare away from them.
      if (kd == KernelType::bspline) {
        EXPECT_NEAR(hess[0][0], 2.5 * kernel_d2(kd, a) * wb * wc / 0.25, 1e-12);
        EXPECT_NEAR(hess[2][2], 2.5 * wa * wb * kernel_d2(kd, c) / (1.25 * 1.25), 1e-12);
      }
    }
  }
}

TEST(VolumeField, BorderReplicatesEdgeVoxels) {
  // Near and beyond the border the field equals that of the volume padded
  // with 3 copies of its edge voxels on every side.
  const Geometry g = oblique_geometry();
  const Dims d{6, 5, 7};
  const Volume v = random_volume(d, g, 11);
  const int pad = 3;
  Geometry gp = g;
  gp.origin = g.index_to_world(Vec3(-pad, -pad, -pad));
  Volume vp(VoxelType::f32, Dims{d.nx + 2 * pad, d.ny + 2 * pad, d.nz + 2 * pad}, gp);
  auto clampi = [](long i, std::size_t n) { return std::size_t(std::min<long>(std::max<long>(i, 0), long(n) - 1)); };
  for (std::size_t k = 0; k < vp.dims().nz; ++k)
    for (std::size_t j = 0; j < vp.dims().ny; ++j)
      for (std::size_t i = 0; i < vp.dims().nx; ++i)
        vp.set(i, j, k, v.get(clampi(long(i) - pad, d.nx), clampi(long(j) - pad, d.ny), clampi(long(k) - pad, d.nz)));
  const VolumeField f(v, kBspline), fp(vp, kBspline);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> tx(-1.5, d.nx + 0.5), ty(-1.5, d.ny + 0.5), tz(-1.5, d.nz + 0.5);
  for (int n = 0; n < 300; ++n) {
    const Vec3 x = g.index_to_world(Vec3(tx(rng), ty(rng), tz(rng)));
    Vec3 g1, g2;
    Mat3 h1, h2;
    EXPECT_NEAR(f.evaluate(x, g1, h1), fp.evaluate(x, g2, h2), 1e-12);
    EXPECT_NEAR(norm(g1 - g2), 0.0, 1e-11);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(h1[r][c], h2[r][c], 1e-10);
  }
  // Far outside: the value of the nearest corner voxel, flat gradient.
  Vec3 grad;
  EXPECT_NEAR(f.value_gradient(g.index_to_world(Vec3(-50, -60, -70)), grad), v.get(0, 0, 0), 1e-6);
  EXPECT_EQ(norm(grad), 0.0);
  EXPECT_NEAR(f.value(g.index_to_world(Vec3(1e12, 40, 1e9))), v.get(d.nx - 1, d.ny - 1, d.nz - 1), 1e-6);
}

TEST(VolumeField, DerivativesMatchCentralDifferences) {
  // Inside a cell F is a tricubic polynomial of t = D^-1 (x - origin), so the
  // central-difference error is (δ²/6)·(a third derivative of F, resp. of
  // ∇F): with |v| <= 1, spacing >= 0.7 and δ = 1e-5 that is < 1e-8, and
  // rounding adds ~1e-16·|F|/δ ~ 1e-11. A wrong chain rule (D^-1 for D^-T,
  // a missing spacing) is off by O(1).
  const Geometry g = oblique_geometry();
  const Volume v = random_volume(Dims{9, 8, 7}, g, 5);
  const double delta = 1e-5, tol = 1e-6;
  for (const VolumeFieldParams& p : {kBspline, kCatmullRom}) {
    const VolumeField f(v, p);
    for (const Vec3& x : cell_interior_points(v, 200, 17)) {
      Vec3 grad, grad_only;
      Mat3 hess;
      const double val = f.evaluate(x, grad, hess);
      EXPECT_NEAR(val, f.value(x), 1e-14);
      EXPECT_NEAR(val, f.value_gradient(x, grad_only), 1e-14);
      EXPECT_NEAR(norm(grad - grad_only), 0.0, 1e-13);
      for (int a = 0; a < 3; ++a) {
        Vec3 e;
        e[a] = delta;
        EXPECT_NEAR(grad[a], (f.value(x + e) - f.value(x - e)) / (2 * delta), tol) << kernel_name(p.value_kernel);
        Vec3 gp, gm;
        f.value_gradient(x + e, gp);
        f.value_gradient(x - e, gm);
        for (int b = 0; b < 3; ++b)
          EXPECT_NEAR(hess[b][a], (gp[b] - gm[b]) / (2 * delta), tol) << kernel_name(p.value_kernel);
      }
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) EXPECT_EQ(hess[a][b], hess[b][a]);
    }
  }
}

TEST(VolumeField, Chapter5MixTakesValueAndDerivativesFromTheirKernels) {
  const Geometry g = oblique_geometry();
  const Volume v = random_volume(Dims{8, 8, 8}, g, 23);
  const VolumeField mix(v, VolumeFieldParams::chapter5_mix()), bs(v, kBspline), cr(v, kCatmullRom);
  for (const Vec3& x : cell_interior_points(v, 100, 29)) {
    Vec3 gm, gb;
    Mat3 hm, hb;
    EXPECT_NEAR(mix.evaluate(x, gm, hm), cr.value(x), 1e-14);
    bs.evaluate(x, gb, hb);
    EXPECT_NEAR(norm(gm - gb), 0.0, 1e-13);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(hm[r][c], hb[r][c], 1e-12);
  }
  EXPECT_EQ(mix.describe(), "volume 8x8x8 catmull-rom/bspline");
  EXPECT_EQ(VolumeField(v, kBspline, "head.nrrd").describe(), "volume head.nrrd bspline");
}

TEST(VolumeField, LinearFunctionGradientInWorldUnits) {
  // Both kernels reproduce linear functions exactly, so away from the border
  // (taps inside) the gradient is a, in world units, up to the float
  // rounding of the samples: |F| <= 6 gives ~4e-7 per sample, ~2e-6 after
  // dividing by a spacing >= 0.7 and summing |weights| <= 2.
  const Geometry g = oblique_geometry();
  const Dims d{12, 10, 9};
  const Vec3 a(0.8, -1.3, 0.45);
  const double b = 0.25;
  const Vec3 mid = g.index_to_world(Vec3(5.5, 4.5, 4));
  const Volume v = sample(d, g, [&](const Vec3& x) { return dot(a, x - mid) + b; });
  std::mt19937 rng(2);
  for (const VolumeFieldParams& p : {kBspline, kCatmullRom, VolumeFieldParams::chapter5_mix()}) {
    const VolumeField f(v, p);
    for (int n = 0; n < 200; ++n) {
      std::uniform_real_distribution<double> tx(1, d.nx - 2.001), ty(1, d.ny - 2.001), tz(1, d.nz - 2.001);
      const Vec3 x = g.index_to_world(Vec3(tx(rng), ty(rng), tz(rng)));
      Vec3 grad;
      Mat3 hess;
      const double val = f.evaluate(x, grad, hess);
      EXPECT_NEAR(val, dot(a, x - mid) + b, 1e-5);
      EXPECT_NEAR(grad.x, a.x, 1e-5);
      EXPECT_NEAR(grad.y, a.y, 1e-5);
      EXPECT_NEAR(grad.z, a.z, 1e-5);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(hess[r][c], 0.0, 1e-5);
    }
  }
}

// Project x onto F = 0 along the gradient (Newton).
Vec3 project(const ScalarField& f, Vec3 x) {
  for (int it = 0; it < 6; ++it) {
    Vec3 g;
    const double v = f.value_gradient(x, g);
    x -= g * (v / norm2(g));
  }
  return x;
}

struct CurvatureError {
  double max_abs = 0;  // largest |mean curvature - 1/R|
  double mean = 0;     // average of (mean curvature - 1/R)
};

// Mean-curvature error over surface points of a sampled signed-distance
// sphere of radius R with voxel size h (B-spline).
CurvatureError sphere_mean_curvature_error(double R, double h) {
  const int n = int(std::ceil(1.4 * R / h));
  const Geometry g = Geometry::with_spacing(h, h, h, Vec3(-n * h, -n * h, -n * h));
  const Volume v = sample(Dims{std::size_t(2 * n + 1), std::size_t(2 * n + 1), std::size_t(2 * n + 1)}, g,
                          [&](const Vec3& x) { return norm(x) - R; });
  const VolumeField f(v);
  CurvatureError err;
  const int count = 300;
  for (int i = 0; i < count; ++i) {  // Fibonacci sphere directions
    const double z = 1 - 2 * (i + 0.5) / count, r = std::sqrt(1 - z * z), phi = 2.399963229728653 * i;
    const Vec3 x = project(f, Vec3(R * r * std::cos(phi), R * r * std::sin(phi), R * z));
    Vec3 grad;
    Mat3 hess;
    EXPECT_LT(std::fabs(f.evaluate(x, grad, hess)), 1e-9);
    const double e = curvature(grad, hess).mean() - 1 / R;
    err.max_abs = std::max(err.max_abs, std::fabs(e));
    err.mean += e / count;
  }
  return err;
}

TEST(VolumeField, SampledSphereMeanCurvature) {
  // The B-spline smooths: F ≈ d + (h²/6)Δd = |x| - R + h²/(3|x|), whose zero
  // set is a sphere of radius ≈ R - h²/(3R), so on average the mean
  // curvature is high by b = h²/(3R³) (checked to 10%). The variation over
  // directions (grid anisotropy) is O(h²) too: allow |error| <= 2b, and the
  // error must shrink about 4x when h halves.
  const double R = 1.0;
  for (double h : {R / 10, R / 20}) {
    const double b = h * h / (3 * R * R * R);
    const CurvatureError e = sphere_mean_curvature_error(R, h);
    EXPECT_NEAR(e.mean, b, 0.1 * b) << "h=" << h;
    EXPECT_LT(e.max_abs, 2 * b) << "h=" << h;
  }
  EXPECT_LT(sphere_mean_curvature_error(R, R / 20).max_abs, 0.3 * sphere_mean_curvature_error(R, R / 10).max_abs);
}

TEST(VolumeField, SampledTorusPrincipalCurvatures) {
  // Signed distance of the torus R = 1, r = 0.4 with h = 0.04 (r/h = 10).
  // Closed forms: outer equator κ = (1/r, 1/(R+r)), inner equator
  // κ = (1/r, -1/(R-r)). The B-spline smoothing biases curvatures by
  // O(h²/r²) relative to the largest one, 1/r (sphere: (h²/3r²)/r, 0.008
  // here; observed 0.012): tolerance (h/r)²/r = 0.025.
  const double Rt = 1.0, rt = 0.4, h = 0.04;
  const int nx = int(std::ceil(1.6 / h)), nz = int(std::ceil(0.6 / h));
  const Geometry g = Geometry::with_spacing(h, h, h, Vec3(-nx * h, -nx * h, -nz * h));
  const Volume v = sample(Dims{std::size_t(2 * nx + 1), std::size_t(2 * nx + 1), std::size_t(2 * nz + 1)}, g,
                          [&](const Vec3& x) { return std::hypot(std::hypot(x.x, x.y) - Rt, x.z) - rt; });
  const VolumeField f(v);
  const double tol = (h / rt) * (h / rt) / rt;
  for (double phi : {0.0, 0.3, 0.7854, 2.0}) {
    const Vec3 dir(std::cos(phi), std::sin(phi), 0);
    for (bool outer : {true, false}) {
      const Vec3 x = project(f, dir * (outer ? Rt + rt : Rt - rt));
      Vec3 grad;
      Mat3 hess;
      f.evaluate(x, grad, hess);
      const Curvature c = curvature(grad, hess);
      EXPECT_NEAR(c.k1, 1 / rt, tol) << "phi=" << phi << (outer ? " outer" : " inner");
      EXPECT_NEAR(c.k2, outer ? 1 / (Rt + rt) : -1 / (Rt - rt), tol) << "phi=" << phi << (outer ? " outer" : " inner");
      EXPECT_NEAR(std::fabs(c.dir2.z), 0.0, 1e-3);  // the ring direction is horizontal
    }
  }
}

TEST(VolumeField, RejectsNonFiniteVoxels) {
  Volume v(VoxelType::f32, Dims{4, 3, 2});
  v.set(2, 1, 1, std::numeric_limits<double>::quiet_NaN());
  v.set(3, 2, 1, std::numeric_limits<double>::infinity());
  try {
    VolumeField f(v, {}, "seg.nrrd");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("\"seg.nrrd\""), std::string::npos) << m;
    EXPECT_NE(m.find("(2,1,1)"), std::string::npos) << m;
    EXPECT_NE(m.find("2 non-finite"), std::string::npos) << m;
  }
  Volume big(VoxelType::f64, Dims{2, 2, 2});
  big.set(1, 0, 0, 1e300);  // finite as double, not as float
  EXPECT_THROW(VolumeField(big, {}, "big"), InputError);
}

TEST(VolumeField, DomainResolutionAndNonFinitePositions) {
  const Geometry g = oblique_geometry();
  const Volume v = random_volume(Dims{5, 6, 7}, g, 1);
  const VolumeField f(v);
  const Box b = f.domain(), w = v.world_bounds();
  EXPECT_EQ(b.lo, w.lo);
  EXPECT_EQ(b.hi, w.hi);
  EXPECT_NEAR(f.resolution(), std::hypot(0.7, 0.1, 0.0), 1e-15);  // the shortest column
  Vec3 grad;
  Mat3 hess;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(std::isnan(f.evaluate(Vec3(nan, 0, 0), grad, hess)));
  EXPECT_TRUE(std::isnan(grad.x) && std::isnan(hess[1][1]));
  // Integer voxels are converted.
  Volume u8(VoxelType::u8, Dims{4, 4, 4});
  u8.set(1, 2, 3, 200);
  EXPECT_NEAR(VolumeField(u8, kCatmullRom).value(Vec3(1, 2, 3)), 200.0, 1e-12);
}


// Bit patterns, so that NaN == NaN and -0 != +0.
std::uint64_t bits(double d) {
  std::uint64_t u;
  std::memcpy(&u, &d, sizeof u);
  return u;
}

// Positions that exercise every branch of the reconstruction: inside, on the
// border nodes, in the clamped band [-2, n+1] around the grid, far outside,
// infinite, and NaN in each coordinate. World units, `g`'s geometry.
std::vector<Vec3> awkward_points(const Volume& v, unsigned seed) {
  const Geometry& g = v.geometry();
  const Dims d = v.dims();
  std::mt19937 rng(seed);
  std::vector<Vec3> pts;
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int n = 0; n < 200; ++n) {  // index space from -4 to n + 3: inside and the clamped band
    Vec3 t;
    for (int a = 0; a < 3; ++a) t[a] = std::uniform_real_distribution<double>(-4.0, double(d[a]) + 3.0)(rng);
    pts.push_back(g.index_to_world(t));
  }
  for (int n = 0; n < 40; ++n) {  // integer positions incl. the border nodes and -2, n+1 exactly
    Vec3 t;
    for (int a = 0; a < 3; ++a) t[a] = std::uniform_int_distribution<int>(-3, int(d[a]) + 2)(rng);
    pts.push_back(g.index_to_world(t));
  }
  pts.push_back(g.index_to_world(Vec3(1e6, -1e6, 0.5)));
  pts.push_back(Vec3(inf, 0, 0));
  pts.push_back(Vec3(0, -inf, 0));
  for (int a = 0; a < 3; ++a) {
    Vec3 x = g.index_to_world(Vec3(1, 1, 1));
    x[a] = nan;
    pts.push_back(x);
  }
  std::shuffle(pts.begin(), pts.end(), rng);  // NaN and clamped points in the middle of batches
  return pts;
}

const VolumeFieldParams kKernelCombos[] = {
    kBspline, kCatmullRom, VolumeFieldParams::chapter5_mix(), {KernelType::bspline, KernelType::catmull_rom}};

// Compares a batch call to single-point calls bit for bit, over sub-batches of
// every length 0..9 (shorter and longer than the prefetch pipeline) and the
// rest, or of the given lengths in turn (then the rest).
void expect_batch_matches_single(const ScalarField& f, const std::vector<Vec3>& pts, const std::string& what,
                                 const std::vector<std::size_t>& lengths = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9}) {
  const std::size_t n = pts.size();
  std::vector<double> fv(n), fg(n), fe(n);
  std::vector<Vec3> gg(n), ge(n);
  std::vector<Mat3> he(n);
  for (std::size_t at = 0, len = 0; at < n; ++len) {
    const std::size_t m = len < lengths.size() ? std::min(lengths[len], n - at) : n - at;
    f.value_batch(pts.data() + at, m, fv.data() + at);
    f.value_gradient_batch(pts.data() + at, m, fg.data() + at, gg.data() + at);
    f.evaluate_batch(pts.data() + at, m, fe.data() + at, ge.data() + at, he.data() + at);
    at += m;
  }
  int mismatches = 0;
  for (std::size_t k = 0; k < n && mismatches < 5; ++k) {
    Vec3 g1, g2;
    Mat3 h2;
    const double v = f.value(pts[k]), vg = f.value_gradient(pts[k], g1), ve = f.evaluate(pts[k], g2, h2);
    bool same = bits(fv[k]) == bits(v) && bits(fg[k]) == bits(vg) && bits(fe[k]) == bits(ve);
    for (int a = 0; a < 3; ++a) {
      same = same && bits(gg[k][a]) == bits(g1[a]) && bits(ge[k][a]) == bits(g2[a]);
      for (int b = 0; b < 3; ++b) same = same && bits(he[k][a][b]) == bits(h2[a][b]);
    }
    if (!same) {
      ++mismatches;
      ADD_FAILURE() << what << ": batch differs from single-point at point " << k << " (" << pts[k].x << ", "
                    << pts[k].y << ", " << pts[k].z << "): value " << fv[k] << " vs " << v;
    }
  }
}

TEST(VolumeField, BatchIsBitIdenticalToSinglePointCalls) {
  // Odd sizes (partial bricks at the far end, where the AVX2 path reads the
  // padding brick), a one-voxel volume, an oblique geometry; every kernel
  // pair, both code paths.
  const Geometry g = oblique_geometry();
  for (const Dims d : {Dims{13, 7, 9}, Dims{4, 2, 2}, Dims{1, 1, 1}, Dims{6, 1, 3}}) {
    const Volume v = random_volume(d, g, 11);
    const std::vector<Vec3> pts = awkward_points(v, 5);
    for (VolumeFieldParams p : kKernelCombos)
      for (bool avx2 : {true, false}) {
        p.allow_avx2 = avx2;
        const VolumeField f(v, p);
        expect_batch_matches_single(f, pts, f.describe() + (f.uses_avx2() ? " avx2" : " baseline"));
      }
  }
}

TEST(VolumeField, Avx2PathGivesTheBaselineBits) {
  // Same IEEE operations in the same order: the run-time choice of code path
  // must not change a single bit (results do not depend on the CPU).
  const Volume v = random_volume(Dims{11, 9, 10}, oblique_geometry(), 3);
  const std::vector<Vec3> pts = awkward_points(v, 8);
  for (VolumeFieldParams p : kKernelCombos) {
    p.allow_avx2 = false;
    const VolumeField base(v, p);
    p.allow_avx2 = true;
    const VolumeField fast(v, p);
    EXPECT_FALSE(base.uses_avx2());
    if (!fast.uses_avx2()) GTEST_SKIP() << "this CPU has no AVX2";
    const std::size_t n = pts.size();
    std::vector<double> f0(n), f1(n);
    std::vector<Vec3> g0(n), g1(n);
    std::vector<Mat3> h0(n), h1(n);
    base.evaluate_batch(pts.data(), n, f0.data(), g0.data(), h0.data());
    fast.evaluate_batch(pts.data(), n, f1.data(), g1.data(), h1.data());
    int differ = 0;
    for (std::size_t k = 0; k < n; ++k) {
      bool same = bits(f0[k]) == bits(f1[k]);
      for (int a = 0; a < 3; ++a) {
        same = same && bits(g0[k][a]) == bits(g1[k][a]);
        for (int b = 0; b < 3; ++b) same = same && bits(h0[k][a][b]) == bits(h1[k][a][b]);
      }
      differ += !same;
    }
    EXPECT_EQ(differ, 0) << base.describe() << ": AVX2 and baseline results differ at " << differ << " of " << n
                         << " points";
    // Value and gradient (order 1), and values alone (order 0): code paths of
    // their own.
    base.value_gradient_batch(pts.data(), n, f0.data(), g0.data());
    fast.value_gradient_batch(pts.data(), n, f1.data(), g1.data());
    for (std::size_t k = 0; k < n; ++k) {
      ASSERT_EQ(bits(f0[k]), bits(f1[k])) << base.describe() << " point " << k;
      for (int a = 0; a < 3; ++a) ASSERT_EQ(bits(g0[k][a]), bits(g1[k][a])) << base.describe() << " point " << k;
    }
    base.value_batch(pts.data(), n, f0.data());
    fast.value_batch(pts.data(), n, f1.data());
    for (std::size_t k = 0; k < n; ++k) ASSERT_EQ(bits(f0[k]), bits(f1[k])) << base.describe() << " point " << k;
  }
}

// n points: uniform in index space over [-3, n_a + 2] (inside, the clamped
// band and beyond) with the awkward points (border nodes, far, infinite,
// NaN) mixed in at random places. World units.
std::vector<Vec3> many_points(const Volume& v, std::size_t n, unsigned seed) {
  std::vector<Vec3> pts = awkward_points(v, seed);
  std::mt19937 rng(seed);
  while (pts.size() < n) {
    Vec3 t;
    for (int a = 0; a < 3; ++a) t[a] = std::uniform_real_distribution<double>(-3.0, double(v.dims()[a]) + 2.0)(rng);
    pts.push_back(v.geometry().index_to_world(t));
  }
  std::shuffle(pts.begin(), pts.end(), rng);
  return pts;
}

TEST(VolumeField, SortedBatchIsBitIdenticalToSinglePointCalls) {
  // Batches evaluated in brick order (sort_min_batch) against single-point
  // calls: sub-batch lengths straddling the threshold, every kernel pair,
  // both code paths. Brick counts: 1 (4x2x2), 80 (13x7x9: one radix digit)
  // and 1100 (37x22x19: two digits from ~64 points on).
  constexpr std::size_t kThreshold = 100;
  const std::vector<std::size_t> lengths = {1, 2, kThreshold - 1, kThreshold, kThreshold + 1, 3, 1000, 64};
  for (const Dims d : {Dims{4, 2, 2}, Dims{13, 7, 9}, Dims{37, 22, 19}}) {
    const Volume v = random_volume(d, oblique_geometry(), 31);
    const std::vector<Vec3> pts = many_points(v, 3000, 9);
    for (VolumeFieldParams p : kKernelCombos)
      for (bool avx2 : {true, false}) {
        p.allow_avx2 = avx2;
        p.sort_min_batch = kThreshold;
        const VolumeField f(v, p);
        ASSERT_FALSE(f.sorts_batch(kThreshold - 1));
        ASSERT_TRUE(f.sorts_batch(kThreshold));
        const std::string what = f.describe() + (f.uses_avx2() ? " avx2" : " baseline") + " sorted from 100";
        expect_batch_matches_single(f, pts, what, lengths);
        p.sort_min_batch = 2;  // every batch but single points, short ones too
        const VolumeField all(v, p);
        expect_batch_matches_single(all, pts, what + " (from 2)");
      }
  }
}

TEST(VolumeField, SortedBatchOfClusteredPoints) {
  // Brick order with ranges of very different sizes: most points in one
  // small cluster (a range of the first radix digit holding nearly the whole
  // batch, which the reused range buffer must take) and the rest spread out
  // (ranges of one or a few points, evaluated from the same buffer after the
  // big one); Hessians included (their slots are written in random order).
  const Volume v = random_volume(Dims{37, 22, 19}, oblique_geometry(), 12);
  std::vector<Vec3> pts = many_points(v, 300, 2);  // spread out, awkward points included
  std::mt19937 rng(6);
  std::normal_distribution<double> near(0.0, 0.7);  // voxels
  while (pts.size() < 6000) pts.push_back(v.geometry().index_to_world(Vec3(20 + near(rng), 11 + near(rng), 9 + near(rng))));
  std::shuffle(pts.begin(), pts.end(), rng);
  for (VolumeFieldParams p : {kBspline, VolumeFieldParams::chapter5_mix()})
    for (bool avx2 : {true, false}) {
      p.allow_avx2 = avx2;
      p.sort_min_batch = 2;
      const VolumeField f(v, p);
      expect_batch_matches_single(f, pts, f.describe() + (f.uses_avx2() ? " avx2" : " baseline") + " clustered",
                                  {pts.size(), 1000, 17});
    }
}

TEST(VolumeField, SortedBatchBeyondOneSortChunk) {
  // Batches are sorted 2^20 points at a time: one batch across that boundary.
  const Volume v = random_volume(Dims{37, 22, 19}, oblique_geometry(), 5);
  const std::vector<Vec3> pts = many_points(v, (std::size_t(1) << 20) + 1001, 3);
  VolumeFieldParams p = VolumeFieldParams::chapter5_mix();
  p.sort_min_batch = 2;
  const VolumeField f(v, p);
  std::vector<double> fb(pts.size());
  std::vector<Vec3> gb(pts.size());
  f.value_gradient_batch(pts.data(), pts.size(), fb.data(), gb.data());
  std::size_t differ = 0, first = pts.size();
  for (std::size_t k = 0; k < pts.size(); ++k) {
    Vec3 g;
    const double v1 = f.value_gradient(pts[k], g);
    const bool same = bits(v1) == bits(fb[k]) && bits(g.x) == bits(gb[k].x) && bits(g.y) == bits(gb[k].y) &&
                      bits(g.z) == bits(gb[k].z);
    if (!same && differ++ == 0) first = k;
  }
  EXPECT_EQ(differ, 0u) << "sorted batch of " << pts.size() << " points differs from single-point calls at "
                        << differ << " points, first " << first;
}

TEST(VolumeField, SortedBatchesFromSeveralThreads) {
  // The sort's scratch is per thread: concurrent batches of different sizes
  // on one field must not disturb each other.
  const Volume v = random_volume(Dims{37, 22, 19}, oblique_geometry(), 8);
  VolumeFieldParams p;
  p.sort_min_batch = 2;
  const VolumeField f(v, p);
  const std::vector<Vec3> pts = many_points(v, 20000, 4);
  std::vector<double> ref(pts.size());
  std::vector<Vec3> gref(pts.size());
  for (std::size_t k = 0; k < pts.size(); ++k) ref[k] = f.value_gradient(pts[k], gref[k]);
  constexpr int kThreads = 4;
  std::vector<std::size_t> bad(kThreads, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      const std::size_t len = std::size_t(97) << t;  // 97 .. 776 points per call
      std::vector<double> fv(len);
      std::vector<Vec3> gv(len);
      for (int rep = 0; rep < 20; ++rep)
        for (std::size_t at = 0; at + len <= pts.size(); at += len) {
          f.value_gradient_batch(pts.data() + at, len, fv.data(), gv.data());
          for (std::size_t k = 0; k < len; ++k)
            bad[t] += bits(fv[k]) != bits(ref[at + k]) || bits(gv[k].x) != bits(gref[at + k].x) ||
                      bits(gv[k].y) != bits(gref[at + k].y) || bits(gv[k].z) != bits(gref[at + k].z);
        }
    });
  for (auto& th : threads) th.join();
  for (int t = 0; t < kThreads; ++t) EXPECT_EQ(bad[t], 0u) << "thread " << t;
}

TEST(VolumeField, SortsLargeBatchesOnLargeVolumesByDefault) {
  // Automatic threshold: volumes of more than 32 MiB of float voxels sort
  // batches of one point per four bricks or more; smaller volumes never.
  const VolumeField small(random_volume(Dims{37, 22, 19}, oblique_geometry(), 1));
  EXPECT_FALSE(small.sorts_batch(std::size_t(1) << 24));
  const Volume big(VoxelType::u8, Dims{256, 256, 160});  // 64 x 128 x 80 bricks: 40 MiB as floats
  const std::size_t bricks = 64 * 128 * 80;
  const VolumeField f(big);
  EXPECT_FALSE(f.sorts_batch(bricks / 4 - 1));
  EXPECT_TRUE(f.sorts_batch(bricks / 4));
  EXPECT_FALSE(f.sorts_batch(1));
  VolumeFieldParams never;
  never.sort_min_batch = SIZE_MAX;
  EXPECT_FALSE(VolumeField(big, never).sorts_batch(std::size_t(1) << 24));
}

TEST(VolumeField, DefaultLargeBatchesMatchSinglePointCalls) {
  // Above the automatic threshold on a large volume: a random walk (coherent,
  // evaluated in its own order) and the same points shuffled (evaluated in
  // brick order), both bit for bit against single-point calls.
  Volume big(VoxelType::u8, Dims{256, 256, 160}, oblique_geometry());
  std::mt19937 rng(17);
  std::uint8_t* d = big.data<std::uint8_t>();
  for (std::size_t k = 0; k < big.count(); ++k) d[k] = std::uint8_t(rng());
  const VolumeField f(big);
  const std::size_t n = 64 * 128 * 80 / 4 + 100;
  ASSERT_TRUE(f.sorts_batch(n));
  std::normal_distribution<double> step(0.0, 0.5);  // voxels
  std::vector<Vec3> pts(n);
  Vec3 t(128, 128, 80);
  for (Vec3& x : pts) {
    for (int a = 0; a < 3; ++a) t[a] = std::clamp(t[a] + step(rng), -1.0, double(big.dims()[a]));
    x = big.geometry().index_to_world(t);
  }
  expect_batch_matches_single(f, pts, "random walk", {n});
  std::shuffle(pts.begin(), pts.end(), rng);
  expect_batch_matches_single(f, pts, "shuffled", {n});
}

TEST(VolumeField, BatchOnALargeVolumeMatchesKernelSums) {
  // A volume beyond the small-test sizes (several brick rows and planes per
  // axis), the batch against a direct 64-tap sum of the kernel products on
  // the plain voxel array: exercises the brick offsets far from the origin.
  const Geometry g = Geometry::with_spacing(0.5, 0.75, 1.0, Vec3(-3, 2, 1));
  const Volume v = random_volume(Dims{37, 22, 19}, g, 21);
  std::mt19937 rng(4);
  std::vector<Vec3> pts, idx;
  for (int n = 0; n < 500; ++n) {
    Vec3 t;
    for (int a = 0; a < 3; ++a) t[a] = std::uniform_real_distribution<double>(1.0, double(v.dims()[a]) - 3.0)(rng);
    idx.push_back(t);
    pts.push_back(g.index_to_world(t));
  }
  for (const VolumeFieldParams& p : {kBspline, VolumeFieldParams::chapter5_mix()}) {
    const VolumeField f(v, p);
    std::vector<double> fv(pts.size());
    std::vector<Vec3> gv(pts.size());
    f.value_gradient_batch(pts.data(), pts.size(), fv.data(), gv.data());
    for (std::size_t k = 0; k < pts.size(); ++k) {
      const Vec3& t = idx[k];
      const int i0 = int(std::floor(t.x)), j0 = int(std::floor(t.y)), k0 = int(std::floor(t.z));
      double val = 0, dx = 0;
      for (int c = -1; c <= 2; ++c)
        for (int b = -1; b <= 2; ++b)
          for (int a = -1; a <= 2; ++a) {
            const double s = v.get(std::size_t(i0 + a), std::size_t(j0 + b), std::size_t(k0 + c));
            val += s * kernel_value(p.value_kernel, t.x - (i0 + a)) * kernel_value(p.value_kernel, t.y - (j0 + b)) *
                   kernel_value(p.value_kernel, t.z - (k0 + c));
            dx += s * kernel_d1(p.deriv_kernel, t.x - (i0 + a)) * kernel_value(p.deriv_kernel, t.y - (j0 + b)) *
                  kernel_value(p.deriv_kernel, t.z - (k0 + c));
          }
      // 64 terms of magnitude <= 1 summed in a different order: rounding
      // differences stay below 64 * 4 ulp(1) ~ 6e-14. dF/dx_world = dF/dt / 0.5.
      ASSERT_NEAR(fv[k], val, 1e-13) << f.describe() << " point " << k;
      ASSERT_NEAR(gv[k].x, dx / 0.5, 1e-12) << f.describe() << " point " << k;
    }
  }
}

TEST(ScalarField, DefaultBatchLoopsOverSinglePointCalls) {
  const auto torus = make_implicit("torus:R=1,r=0.3");
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  std::vector<Vec3> pts(37);
  for (auto& x : pts) x = Vec3(u(rng), u(rng), u(rng));
  pts[5] = Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0);
  expect_batch_matches_single(*torus, pts, torus->describe());
}


// --- value bounds (ValueBounds) ---------------------------------------------------

// Points spread over the whole grid, block edges and the grid's last cell included.
std::vector<Vec3> bound_probe_points(const Volume& v, int block, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<Vec3> pts;
  const Dims& d = v.dims();
  for (int n = 0; n < 6000; ++n) {
    Vec3 t;
    // (the grid's border itself may round to just outside it: at() says false there)
    for (int a = 0; a < 3; ++a) t[a] = std::uniform_real_distribution<double>(1e-9, double(d[a] - 1) - 1e-9)(rng);
    if (n % 5 == 0)  // on a block edge along one axis
      t[n % 3] = block * std::uniform_int_distribution<int>(1, int(d[n % 3] - 2) / block)(rng);
    pts.push_back(v.geometry().index_to_world(t));
  }
  pts.push_back(v.geometry().index_to_world(Vec3(d[0] - 1.000001, d[1] - 1.000001, d[2] - 1.000001)));
  return pts;
}

TEST(VolumeField, ValueBoundsHoldAtEveryPoint) {
  // Random voxels make the worst case for the overshoot of Catmull-Rom's
  // negative lobes; the bounds must hold for both kernels and every block.
  const Volume v = random_volume(Dims{23, 17, 19}, oblique_geometry(), 5);
  for (const VolumeFieldParams& p : {kBspline, kCatmullRom}) {
    const VolumeField f(v, p);
    const NegatedField neg(f);
    for (int block : {1, 3, 4}) {
      const auto b = f.value_bounds(block);
      const auto nb = neg.value_bounds(block);
      ASSERT_TRUE(b && nb);
      double worst_slack = 1e300;
      for (const Vec3& x : bound_probe_points(v, block, 9)) {
        double lo, hi, nlo, nhi;
        ASSERT_TRUE(b->at(x, lo, hi));
        ASSERT_TRUE(nb->at(x, nlo, nhi));
        const double fx = f.value(x);
        EXPECT_LE(lo, fx);
        EXPECT_GE(hi, fx);
        EXPECT_EQ(nlo, -hi);
        EXPECT_EQ(nhi, -lo);
        worst_slack = std::min(worst_slack, std::min(fx - lo, hi - fx));
      }
      // Not vacuous: the bounds come within a voxel value range (2) of the field.
      EXPECT_LT(worst_slack, 2.0) << block;
    }
    double lo, hi;
    EXPECT_FALSE(f.value_bounds(4)->at(oblique_geometry().index_to_world(Vec3(-0.5, 3, 3)), lo, hi));
    EXPECT_FALSE(f.value_bounds(4)->at(Vec3(std::nan(""), 0, 0), lo, hi));
  }
  EXPECT_THROW(VolumeField(v, kBspline).value_bounds(0), UsageError);
}

TEST(VolumeField, ValueBoundsAreTheSameWhoeverAsksFirst) {
  // Blocks are computed on first use, from whichever thread asks: bounds
  // asked for by many threads at once (each block by several) equal those of
  // a fresh object asked one point at a time, and the negated bounds share
  // the blocks the plain ones computed.
  const Volume v = random_volume(Dims{31, 27, 22}, oblique_geometry(), 11);
  const VolumeField f(v, kCatmullRom);
  const NegatedField neg(f);
  const std::vector<Vec3> pts = bound_probe_points(v, 4, 21);
  const auto shared = f.value_bounds(4);
  const auto shared_neg = neg.value_bounds(4);
  const std::size_t n = pts.size();
  std::vector<double> lo(4 * n, -1), hi(4 * n, -1);
  tbb::parallel_for(std::size_t(0), 4 * n, [&](std::size_t q) { shared->at(pts[q % n], lo[q], hi[q]); });
  const auto fresh = f.value_bounds(4);
  for (std::size_t k = 0; k < n; ++k) {
    double l, h, nl, nh;
    ASSERT_TRUE(fresh->at(pts[k], l, h));
    for (std::size_t c = 0; c < 4; ++c) {
      EXPECT_EQ(lo[k + c * n], l);
      EXPECT_EQ(hi[k + c * n], h);
    }
    ASSERT_TRUE(shared_neg->at(pts[k], nl, nh));
    EXPECT_EQ(nl, -h);
    EXPECT_EQ(nh, -l);
  }
}

TEST(VolumeField, ValueBoundsOfALinearFieldAreTheFitAlone) {
  // Both kernels reproduce linear functions: the residual is 0, so a
  // block's bounds are its linear extent, block × Σ|slope in index units|.
  const Geometry g = oblique_geometry();
  const Vec3 grad(0.3, -0.2, 0.5);
  const Volume v = sample(Dims{20, 18, 21}, g, [&](const Vec3& x) { return 1.0 + dot(grad, x); });
  const Vec3 gi = transpose(g.directions) * grad;  // d/dt of F(origin + D t)
  const double extent = std::fabs(gi.x) + std::fabs(gi.y) + std::fabs(gi.z);
  for (const VolumeFieldParams& p : {kBspline, kCatmullRom}) {
    const VolumeField f(v, p);
    const auto b = f.value_bounds(4);
    for (const Vec3& x : bound_probe_points(v, 4, 3)) {
      double lo, hi;
      ASSERT_TRUE(b->at(x, lo, hi));
      EXPECT_LE(lo, f.value(x));
      EXPECT_GE(hi, f.value(x));
      // Where the block's samples are all inside the grid (the border
      // replicates, which is not linear): float voxels leave residuals ~1e-6.
      const Vec3 t = inverse(g.directions) * (x - g.origin);
      bool inside = true;
      for (int a = 0; a < 3; ++a) {
        const int bk = int(t[a]) / 4;
        inside = inside && bk >= 1 && bk * 4 + 5 <= int(v.dims()[a]) - 1;
      }
      if (inside) EXPECT_LE(hi - lo, 4 * extent + 1e-4);
    }
  }
}

}  // namespace
}  // namespace pm
