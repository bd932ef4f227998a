#include "pm/volume/tighten.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <random>

#include "pm/base/error.h"
#include "pm/field/curvature.h"
#include "pm/field/distance.h"
#include "pm/field/volume_field.h"

namespace pm {
namespace {

Volume mask_of(Dims d, const Geometry& g, const std::function<bool(const Vec3&)>& in) {
  Volume v(VoxelType::u8, d, g);
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      for (std::size_t i = 0; i < d.nx; ++i)
        v.set(i, j, k, in(g.index_to_world(Vec3(double(i), double(j), double(k)))) ? 1 : 0);
  return v;
}

// Zero-set points of a distance volume: linear crossings along the grid edges.
std::vector<Vec3> zero_set(const Volume& d) {
  std::vector<Vec3> pts;
  const Dims& n = d.dims();
  for (std::size_t k = 0; k < n.nz; ++k)
    for (std::size_t j = 0; j < n.ny; ++j)
      for (std::size_t i = 0; i < n.nx; ++i) {
        const double a = d.get(i, j, k);
        const std::size_t nb[3][3] = {{i + 1, j, k}, {i, j + 1, k}, {i, j, k + 1}};
        for (const auto& q : nb) {
          if (q[0] >= n.nx || q[1] >= n.ny || q[2] >= n.nz) continue;
          const double b = d.get(q[0], q[1], q[2]);
          if ((a < 0) == (b < 0)) continue;
          const double t = a / (a - b);
          const Vec3 x0{double(i), double(j), double(k)};
          const Vec3 x1{double(q[0]), double(q[1]), double(q[2])};
          pts.push_back(d.geometry().index_to_world(x0 + (x1 - x0) * t));
        }
      }
  return pts;
}

// Largest principal curvature magnitude over the zero set (B-spline reconstruction).
double max_curvature(const Volume& d) {
  const VolumeField f(d);
  double worst = 0;
  for (const Vec3& x : zero_set(d)) {
    Vec3 g;
    Mat3 H;
    f.evaluate(x, g, H);
    const Curvature c = curvature(g, H);
    worst = std::max(worst, std::max(std::fabs(c.k1), std::fabs(c.k2)));
  }
  return worst;
}

TEST(Tighten, FlowStepAvx2CopyAgreesBitForBit) {
  // The flow's AVX2 copy (four nodes at a time, gathers or, for runs along
  // x, plain loads) against the baseline loop: the same next values and the
  // same largest zero-set move, for shells of active nodes with runs and
  // gaps, values of both signs near zero, clamps that bind and a run of
  // exact zeros, on an anisotropic grid. Without AVX2 both are the baseline.
  const Dims box{23, 19, 17};
  const double h[3] = {0.7, 1.0, 1.9};
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.5f, 1.5f);
  std::vector<float> cur(box.count());
  for (float& v : cur) v = u(rng);
  for (std::size_t c = 400; c < 420; ++c) cur[c] = 0.f;
  std::vector<std::uint32_t> active;
  std::bernoulli_distribution take(0.6);
  for (std::size_t k = 1; k + 1 < box.nz; ++k)
    for (std::size_t j = 1; j + 1 < box.ny; ++j)
      for (std::size_t i = 1; i + 1 < box.nx; ++i)
        if (take(rng)) active.push_back(std::uint32_t(i + box.nx * (j + box.ny * k)));
  ASSERT_GT(active.size(), 1000u);
  std::vector<float> lo(active.size()), hi(active.size());
  for (std::size_t t = 0; t < active.size(); ++t) {
    const float a = cur[active[t]] + 0.2f * u(rng), b = cur[active[t]] + 0.2f * u(rng);
    lo[t] = std::min(a, b);
    hi[t] = std::max(a, b);
  }
  const double dt = 0.45 / (1 / (h[0] * h[0]) + 1 / (h[1] * h[1]) + 1 / (h[2] * h[2]));
  std::vector<float> base = cur, fast = cur;
  const double m0 = detail::tighten_flow_step(active, box, cur, base, lo, hi, h, dt, 1.5 * 1.9, false);
  const double m1 = detail::tighten_flow_step(active, box, cur, fast, lo, hi, h, dt, 1.5 * 1.9, true);
  EXPECT_GT(m0, 0.0);
  EXPECT_EQ(std::memcmp(&m0, &m1, sizeof m0), 0) << m0 << " vs " << m1;
  std::size_t moved = 0;
  for (std::size_t c = 0; c < cur.size(); ++c) {
    ASSERT_EQ(std::memcmp(&base[c], &fast[c], sizeof(float)), 0)
        << "node " << c << ": " << base[c] << " vs " << fast[c];
    moved += base[c] != cur[c];
  }
  EXPECT_GT(moved, active.size() / 2);  // the step did something
}

TEST(Tighten, DefaultsFromTheHeader) {
  // Anisotropic CT voxels: the radius is the largest spacing, no upsampling.
  const Volume ct(VoxelType::u8, Dims{20, 20, 10}, Geometry::with_spacing(0.62, 0.62, 1.33));
  TightenDefaults d = tighten_defaults(ct, 0, 0);
  EXPECT_DOUBLE_EQ(d.radius, 1.33);
  EXPECT_EQ(d.upsample, 1);
  // A 2x2x2 label map: upsampled 8 times (16 / 2, capped at 8), radius one fine voxel.
  const Volume tiny(VoxelType::u8, Dims{2, 2, 2});
  d = tighten_defaults(tiny, 0, 0);
  EXPECT_EQ(d.upsample, 8);
  EXPECT_DOUBLE_EQ(d.radius, 0.125);
  // Thin along one axis (4 voxels of 2 mm): K = 16 / 4 = 4, radius 2 / 4.
  const Volume slab(VoxelType::u8, Dims{4, 30, 30}, Geometry::with_spacing(2, 2, 2));
  d = tighten_defaults(slab, 0, 0);
  EXPECT_EQ(d.upsample, 4);
  EXPECT_DOUBLE_EQ(d.radius, 0.5);
  // Given values stay; a given K does not divide the automatic radius.
  d = tighten_defaults(tiny, 3, 0);
  EXPECT_DOUBLE_EQ(d.radius, 3);
  EXPECT_EQ(d.upsample, 8);
  d = tighten_defaults(ct, 0, 2);
  EXPECT_DOUBLE_EQ(d.radius, 1.33);
  EXPECT_EQ(d.upsample, 2);
}

TEST(Tighten, BinaryMaskChecks) {
  Volume grey(VoxelType::f32, {187, 1, 1});
  for (std::size_t i = 0; i < 187; ++i) grey.set(i, 0, 0, 0.5 * double(i));
  try {
    binary_mask_inside(grey);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected a binary mask (2 distinct values), got 187 values"),
              std::string::npos)
        << e.what();
  }
  Volume flat(VoxelType::u8, {3, 3, 3});
  try {
    binary_mask_inside(flat);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("empty mask"), std::string::npos) << e.what();
  }
  Volume m(VoxelType::i16, {2, 1, 1});
  m.set(0, 0, 0, -3);
  m.set(1, 0, 0, 255);
  const auto in = binary_mask_inside(m);
  EXPECT_EQ(in[0], 0);
  EXPECT_EQ(in[1], 1);  // the larger value is inside
}

TEST(Tighten, CubeCurvatureBoundedAndInsideMortar) {
  const double r = 4;
  const Geometry g = Geometry::with_spacing(1, 1, 1);
  const Volume box = mask_of({40, 40, 40}, g, [](const Vec3& x) {
    return x.x >= 10 && x.x <= 29 && x.y >= 10 && x.y <= 29 && x.z >= 10 && x.z <= 29;
  });
  // The untightened box has curvature far above 1/r at its edges: the bound below can fail.
  EXPECT_GT(max_curvature(mask_signed_distance(box)), 2.0 / r);

  TightenParams p;
  p.radius = r;
  p.keep_mortar = true;
  const TightenResult t = tighten(box, p);
  EXPECT_EQ(t.pad, 0u);
  EXPECT_TRUE(t.converged);
  EXPECT_LE(max_curvature(t.distance), 1.1 / r);

  // Every zero-set point lies in the mortar: outside the round, inside the fillet.
  const VolumeField round(t.round, VolumeFieldParams{KernelType::catmull_rom, KernelType::catmull_rom});
  const VolumeField fillet(t.fillet, VolumeFieldParams{KernelType::catmull_rom, KernelType::catmull_rom});
  const double tol = 0.1;  // voxels
  double worst_round = 1e9, worst_fillet = -1e9;
  for (const Vec3& x : zero_set(t.distance)) {
    worst_round = std::min(worst_round, round.value(x));
    worst_fillet = std::max(worst_fillet, fillet.value(x));
  }
  EXPECT_GE(worst_round, -tol);
  EXPECT_LE(worst_fillet, tol);
}

TEST(Tighten, LargeSphereNearlyUnchanged) {
  const double R = 12;
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-18, -18, -18));
  const Volume ball = mask_of({37, 37, 37}, g, [&](const Vec3& x) { return norm(x) <= R; });
  TightenParams p;
  p.radius = 2;
  const TightenResult t = tighten(ball, p);
  // Mean radius of the zero set before (about R) and after: a convex shape
  // settles on its round, a few tenths of a voxel inside the staircase.
  auto radii = [](const Volume& d, double& lo, double& hi) {
    double sum = 0;
    lo = 1e9;
    hi = 0;
    const auto pts = zero_set(d);
    for (const Vec3& x : pts) {
      lo = std::min(lo, norm(x));
      hi = std::max(hi, norm(x));
      sum += norm(x);
    }
    return sum / double(pts.size());
  };
  double lo0, hi0, lo, hi;
  const double before = radii(mask_signed_distance(ball), lo0, hi0);
  const double after = radii(t.distance, lo, hi);
  EXPECT_NEAR(before, R, 0.1);
  EXPECT_NEAR(after, before, 0.3);
  EXPECT_LT(hi - lo, hi0 - lo0);  // smoother: a narrower spread of radii
  EXPECT_GT(lo, R - 0.6);
  EXPECT_LT(hi, R + 0.6);
  EXPECT_LE(max_curvature(t.distance), 1.1 / p.radius);
}

// A mask thinner than 2r everywhere has an empty round: the flow would shrink
// it away. It must survive, tightened at a smaller radius (or untightened).
TEST(Tighten, ThinMaskIsNeverErased) {
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-10, -10, -10));
  for (const double rb : {0.0, 1.0}) {  // a single voxel, a cross of 7
    const Volume ball = mask_of({21, 21, 21}, g, [&](const Vec3& x) { return norm(x) <= rb; });
    TightenParams p;
    p.radius = 4;
    const TightenResult t = tighten(ball, p);
    EXPECT_EQ(t.requested_radius, 4);
    EXPECT_LT(t.radius, 4 / 2.0 + 1e-12) << rb;
    const auto pts = zero_set(t.distance);
    ASSERT_FALSE(pts.empty()) << rb;
    Vec3 c;
    for (const Vec3& x : pts) {
      c = c + x / double(pts.size());
      // inside the mask's own solid (the level 0.5 between voxels) plus half a voxel
      EXPECT_LE(norm(x), rb + 1.0) << rb;
    }
    EXPECT_LT(norm(c), 0.1) << rb;  // the ball and the voxel are symmetric about the origin
  }
  // Dually, a mask filling its (unpadded) box but for a one-voxel hole keeps the hole.
  {
    const Volume holed = mask_of({21, 21, 21}, g, [&](const Vec3& x) { return norm(x) > 0.5; });
    TightenParams p;
    p.radius = 4;
    p.pad = 0;
    const TightenResult t = tighten(holed, p);
    EXPECT_LT(t.radius, 4 / 2.0 + 1e-12);
    const auto pts = zero_set(t.distance);
    ASSERT_FALSE(pts.empty());
    for (const Vec3& x : pts) EXPECT_LE(norm(x), 1.0);
  }
  // A ball that a radius-2 opening keeps is tightened at the radius asked for.
  const Volume big = mask_of({21, 21, 21}, g, [&](const Vec3& x) { return norm(x) <= 6; });
  TightenParams p;
  p.radius = 2;
  const TightenResult t = tighten(big, p);
  EXPECT_EQ(t.radius, 2);
  EXPECT_EQ(t.requested_radius, 2);
}

TEST(Tighten, PadsMaskTouchingTheBorder) {
  const Geometry g = Geometry::with_spacing(2, 2, 2, Vec3(10, 20, 30));
  const Volume m = mask_of({12, 12, 12}, g, [&](const Vec3& x) { return x.x <= 18; });  // slab at the border
  TightenParams p;
  p.radius = 2;
  const TightenResult t = tighten(m, p);
  ASSERT_EQ(t.pad, 4u);  // ceil(r/h) + 3 voxels
  EXPECT_EQ(t.distance.dims().nx, 12u + 8u);
  EXPECT_NEAR(t.distance.geometry().origin.x, 10 - 8, 1e-12);
  EXPECT_NEAR(t.distance.geometry().origin.z, 30 - 8, 1e-12);
  // The slab's face x = 19 (halfway between nodes 18 and 20) is flat: unchanged.
  const VolumeField f(t.distance, VolumeFieldParams{KernelType::catmull_rom, KernelType::catmull_rom});
  EXPECT_NEAR(f.value(Vec3(19, 31, 41)), 0.0, 0.05);
  EXPECT_NEAR(f.value(Vec3(24, 31, 41)), 5.0, 0.1);
}

TEST(Tighten, UpsampleAndSign) {
  const double R = 5;
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-9, -9, -9));
  const Volume ball = mask_of({19, 19, 19}, g, [&](const Vec3& x) { return norm(x) <= R; });
  TightenParams p;
  p.radius = 0.6;
  p.upsample = 2;
  p.positive_inside = true;
  const TightenResult t = tighten(ball, p);
  EXPECT_EQ(t.distance.dims().nx, 37u);
  EXPECT_NEAR(t.distance.geometry().spacing(0), 0.5, 1e-12);
  EXPECT_NEAR(t.distance.geometry().origin.x, -9, 1e-12);
  const VolumeField f(t.distance, VolumeFieldParams{KernelType::catmull_rom, KernelType::catmull_rom});
  EXPECT_GT(f.value(Vec3(0, 0, 0)), 4.5);   // positive inside
  EXPECT_LT(f.value(Vec3(0, 0, 7)), -1.5);  // negative outside
  double sum = 0;
  const auto pts = zero_set(t.distance);
  for (const Vec3& x : pts) sum += norm(x);
  EXPECT_NEAR(sum / double(pts.size()), R, 0.3);  // the voxelised surface is about R
}

TEST(Tighten, RejectsBadRadius) {
  Volume m(VoxelType::u8, {8, 8, 8});
  m.set(4, 4, 4, 1);
  TightenParams p;
  p.radius = 0;
  EXPECT_THROW(tighten(m, p), UsageError);
  p.radius = 1;
  p.upsample = 0;
  EXPECT_THROW(tighten(m, p), UsageError);
}

// tighten_labels runs labels side by side on several threads and hands them
// on in label order; the distances are those of one label at a time, bit for
// bit, and a sink that fails stops the hand-over at that label.
TEST(Tighten, PerLabelSideBySideEqualsOneAtATime) {
  Volume lv(VoxelType::u8, {18, 16, 14});
  for (std::size_t k = 0; k < 14; ++k)
    for (std::size_t j = 0; j < 16; ++j)
      for (std::size_t i = 0; i < 18; ++i) {
        int l = i < 8 ? 0 : 3;
        if (i >= 2 && i < 6 && j >= 3 && j < 12 && k >= 4 && k < 10) l = 1;
        if (i >= 10 && i < 16 && j >= 5 && j < 11 && k >= 3 && k < 11) l = 2;
        lv.set(i, j, k, l);
      }
  TightenParams p;
  p.radius = 1;
  auto run = [&](int threads) {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
    std::vector<std::pair<int, std::vector<float>>> out;
    tighten_labels(lv, p, [&](int l, TightenResult&& r) {
      const float* f = r.distance.data<float>();
      out.emplace_back(l, std::vector<float>(f, f + r.distance.count()));
    });
    return out;
  };
  const auto one = run(1), four = run(4);
  ASSERT_EQ(one.size(), 4u);
  ASSERT_EQ(four.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(one[k].first, int(k));
    EXPECT_EQ(four[k].first, int(k));
    EXPECT_TRUE(one[k].second == four[k].second) << "label " << k;
  }
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 4);
  std::vector<int> seen;
  EXPECT_THROW(tighten_labels(lv, p,
                              [&](int l, TightenResult&&) {
                                if (l == 2) throw InputError("sink refused label 2");
                                seen.push_back(l);
                              }),
               InputError);
  EXPECT_EQ(seen, (std::vector<int>{0, 1}));
}

// Chapter 6: a 20^3 label map, label 1 for x < 9.5, label 2 beyond, and a
// 6^3 cube of label 5 inside label 2.
TEST(Tighten, PerLabelSharesOneGridAndIgnoresTheBorder) {
  Volume lv(VoxelType::u16, {20, 20, 20});
  for (std::size_t k = 0; k < 20; ++k)
    for (std::size_t j = 0; j < 20; ++j)
      for (std::size_t i = 0; i < 20; ++i) {
        int l = i < 10 ? 1 : 2;
        if (i >= 12 && i < 18 && j >= 7 && j < 13 && k >= 7 && k < 13) l = 5;
        lv.set(i, j, k, l);
      }
  TightenParams p;
  p.radius = 1;
  std::vector<int> labels;
  std::vector<Volume> d;
  tighten_labels(lv, p, [&](int l, TightenResult&& r) {
    labels.push_back(l);
    EXPECT_EQ(r.pad, 0u);
    d.push_back(std::move(r.distance));
  });
  ASSERT_EQ(labels, (std::vector<int>{1, 2, 5}));
  for (const Volume& v : d) {
    EXPECT_TRUE(v.dims() == lv.dims());
    EXPECT_NEAR(v.geometry().origin.x, 0.0, 1e-12);
  }
  // The flat 1|2 interface (x = 9.5) away from the cube stays put: at the node
  // x = 9 the distances are -0.5 (label 1) and +0.5 (label 2) within the
  // distance transform's error.
  EXPECT_NEAR(d[0].get(9, 2, 2), -0.5, 0.15);
  EXPECT_NEAR(d[1].get(9, 2, 2), 0.5, 0.15);
  // The volume border is not an interface: the corner node of label 1 is
  // 9.5 away from label 1's only surface (x = 9.5), not half a voxel.
  EXPECT_LT(d[0].get(0, 0, 0), -9.0);
  EXPECT_LT(d[1].get(19, 0, 19), -5.0);
  // The cube is tightened (corners rounded with r = 1) but kept: its centre is inside.
  EXPECT_LT(d[2].get(15, 10, 10), -2.0);
  EXPECT_GT(d[2].get(5, 10, 10), 5.0);
  Volume one(VoxelType::u8, {6, 6, 6});
  EXPECT_THROW(tighten_labels(one, p, [](int, TightenResult&&) {}), InputError);
  Volume frac(VoxelType::f32, {6, 6, 6});
  frac.set(1, 1, 1, 0.5);
  EXPECT_THROW(tighten_labels(frac, p, [](int, TightenResult&&) {}), InputError);
}

}  // namespace
}  // namespace pm
