#include "pm/volume/sizingfield.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <functional>

#include "pm/base/error.h"
#include "pm/volume/medialaxis.h"

namespace pm {
namespace {

Volume sample(Dims d, const Geometry& g, const std::function<double(const Vec3&)>& F) {
  Volume v(VoxelType::f32, d, g);
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      for (std::size_t i = 0; i < d.nx; ++i)
        v.set(i, j, k, F(g.index_to_world(Vec3(double(i), double(j), double(k)))));
  return v;
}

// Calls f(node value of sdf, h, lfs) for every node.
void each_node(const Volume& sdf, const SizingFieldResult& r, const std::function<void(double, double, double)>& f) {
  for (std::size_t c = 0; c < sdf.count(); ++c) f(sdf.get(c), r.h.get(c), r.lfs.get(c));
}

TEST(SizingField, SphereLfsIsRadius) {
  const double R = 8;
  const Vec3 c(0.2, -0.3, 0.1);
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-13, -13, -13));
  const Volume sdf = sample({27, 27, 27}, g, [&](const Vec3& x) { return norm(x - c) - R; });
  const std::vector<Vec3> ma = medial_axis(sdf).points.vertices;
  ASSERT_FALSE(ma.empty());
  SizingFieldParams p;  // eps 0.5, contraction 1.5
  const SizingFieldResult r = sizing_field({{sdf, ma}}, p);
  std::size_t near = 0;
  each_node(sdf, r, [&](double d, double h, double lfs) {
    if (std::fabs(d) > 4) {
      EXPECT_EQ(h, 0);  // outside the band: unknown
      return;
    }
    EXPECT_GT(h, 0);
    if (std::fabs(d) < 1) {
      ++near;
      EXPECT_NEAR(lfs, R, 1.0);
      EXPECT_NEAR(h, 2 * 0.5 * R / 1.5, 1.0 / 1.5);  // λ = 1/κ = R, within a voxel
    }
  });
  EXPECT_GT(near, 500u);
  EXPECT_NEAR(r.lfs_lo, R, 1.0);  // foot points: every band node sees the sphere's own LFS
}

// The nearest-point search (k-d tree with box pruning and a warm start from
// the previous node's answer) must return the exact minimum: checked against
// brute force at every band node (at the node, no foot point) for a noisy
// medial sheet, where many points lie at almost the same distance.
TEST(SizingField, LfsIsExactNearestMedialPoint) {
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-12, -12, -12));
  const Volume sdf = sample({25, 25, 25}, g, [&](const Vec3& x) { return std::fabs(x.z - 0.3) - 7.2; });
  std::vector<Vec3> ma;
  std::uint32_t s = 12345;
  auto rnd = [&] {
    s = s * 1664525u + 1013904223u;
    return double(s >> 8) / double(1u << 24);
  };
  for (int q = 0; q < 3000; ++q) ma.emplace_back(-12 + 24 * rnd(), -12 + 24 * rnd(), 0.3 + 0.2 * (rnd() - 0.5));
  ma.emplace_back(3.3, -4.4, 0.29);  // duplicates and ties must not matter
  ma.emplace_back(3.3, -4.4, 0.29);
  SizingFieldParams p;
  p.at_foot_point = false;
  const SizingFieldResult r = sizing_field({{sdf, ma}}, p);
  std::size_t checked = 0;
  for (std::size_t c = 0; c < sdf.count(); ++c) {
    if (r.lfs.get(c) == 0) continue;
    const Dims& d = sdf.dims();
    const Vec3 x = g.index_to_world(Vec3(double(c % d.nx), double((c / d.nx) % d.ny), double(c / (d.nx * d.ny))));
    double best = 1e300;
    for (const Vec3& m : ma) best = std::min(best, norm2(m - x));
    ASSERT_EQ(r.lfs.get(c), double(float(std::max(std::sqrt(best), 1e-3)))) << "node " << c;
    ++checked;
  }
  EXPECT_GT(checked, 5000u);
}

// medialaxis --lfs-only: the MA points beyond medial_axis_lfs_bound are
// nobody's nearest, so the sizing field is the same, bit for bit. Two balls
// in a wide box: the far bisector plane goes, the centres stay.
TEST(SizingField, LfsBoundedMedialAxisGivesTheSameField) {
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-24, -24, -24));
  const Volume sdf = sample({49, 49, 49}, g, [](const Vec3& x) {
    return std::min(norm(x - Vec3(-5.1, 0.2, 0.3)), norm(x - Vec3(5.3, -0.1, 0.2))) - 4;
  });
  const std::vector<Vec3> all = medial_axis(sdf).points.vertices;
  MedialAxisParams mp;
  mp.max_distance = medial_axis_lfs_bound(sdf);
  const std::vector<Vec3> near = medial_axis(sdf, mp).points.vertices;
  ASSERT_LT(near.size() + 100, all.size());  // the bound (about 11.5) drops most of the plane
  const SizingFieldResult a = sizing_field({{sdf, all}}), b = sizing_field({{sdf, near}});
  ASSERT_GT(a.known, 1000u);
  for (std::size_t c = 0; c < sdf.count(); ++c) {
    ASSERT_EQ(a.lfs.get(c), b.lfs.get(c)) << "node " << c;
    ASSERT_EQ(a.h.get(c), b.h.get(c)) << "node " << c;
  }
}

TEST(SizingField, SlabLfsIsHalfThickness) {
  const double t = 6;
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-6, -6, -8.4));
  const Volume sdf = sample({13, 13, 18}, g, [&](const Vec3& x) { return std::fabs(x.z) - t / 2; });
  const std::vector<Vec3> ma = medial_axis(sdf).points.vertices;
  SizingFieldParams p;
  p.contract = false;
  p.eps = 0.4;
  const SizingFieldResult r = sizing_field({{sdf, ma}}, p);
  std::size_t n = 0;
  for (std::size_t k = 0; k < 18; ++k)
    for (std::size_t j = 2; j <= 10; ++j)  // away from the x and y borders, where the
      for (std::size_t i = 2; i <= 10; ++i) {  // medial axis is cut off
        if (std::fabs(sdf.get(i, j, k)) >= 1) continue;
        ++n;
        EXPECT_NEAR(r.lfs.get(i, j, k), t / 2, 0.3);
        EXPECT_NEAR(r.h.get(i, j, k), 2 * 0.4 * r.lfs.get(i, j, k), 1e-4);  // flat: curvature never wins
      }
  EXPECT_GT(n, 100u);
  EXPECT_EQ(r.curvature_limited, 0u);
}

TEST(SizingField, CurvatureTakesOverWhenSmaller) {
  // A small sphere whose "medial axis" is a far point: λ is large, 1/κ = R decides.
  const double R = 3;
  const Geometry g = Geometry::with_spacing(0.5, 0.5, 0.5, Vec3(-5, -5, -5));
  const Volume sdf = sample({21, 21, 21}, g, [&](const Vec3& x) { return norm(x) - R; });
  const std::vector<Vec3> far{Vec3(40, 0, 0)};
  const SizingFieldResult r = sizing_field({{sdf, far}});
  EXPECT_EQ(r.curvature_limited, r.known);
  each_node(sdf, r, [&](double d, double h, double lfs) {
    if (std::fabs(d) >= 0.5) return;
    EXPECT_GT(lfs, 30);
    EXPECT_NEAR(h, 2 * 0.5 * R / 1.5, 0.05);
  });
}

TEST(SizingField, HminBandAndSeveralSurfaces) {
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-10, -6, -6));
  const Dims dims{21, 13, 13};
  const Vec3 c1(-4, 0, 0), c2(4.5, 0, 0);
  const Volume a = sample(dims, g, [&](const Vec3& x) { return norm(x - c1) - 4; });
  const Volume b = sample(dims, g, [&](const Vec3& x) { return norm(x - c2) - 2; });
  const std::vector<Vec3> ma_a{c1}, ma_b{c2};
  SizingFieldParams p;
  p.band = 2;
  p.hmin = 1.5;
  const SizingFieldResult r = sizing_field({{a, ma_a}, {b, ma_b}}, p);
  for (std::size_t k = 0; k < dims.nz; ++k)
    for (std::size_t j = 0; j < dims.ny; ++j)
      for (std::size_t i = 0; i < dims.nx; ++i) {
        const double da = a.get(i, j, k), db = b.get(i, j, k), h = r.h.get(i, j, k);
        if (std::fabs(da) > 2 && std::fabs(db) > 2) {
          EXPECT_EQ(h, 0);
          continue;
        }
        EXPECT_GE(h, 1.5 - 1e-6);  // hmin
        if (std::fabs(db) <= 2) EXPECT_NEAR(h, 1.5, 1e-4);  // 2·0.5·2/1.5 = 1.33 raised to hmin
        else EXPECT_NEAR(h, 2 * 0.5 * 4 / 1.5, 0.3);
      }
  EXPECT_GT(r.hmin_limited, 0u);
}

TEST(SizingField, BadInput) {
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-5, -5, -5));
  const Volume sdf = sample({11, 11, 11}, g, [](const Vec3& x) { return norm(x) - 3; });
  const std::vector<Vec3> ma{Vec3()}, none;
  SizingFieldParams p;
  p.eps = 0;
  EXPECT_THROW(sizing_field({{sdf, ma}}, p), UsageError);
  p.eps = 0.5;
  p.hmin = -1;
  EXPECT_THROW(sizing_field({{sdf, ma}}, p), UsageError);
  p.hmin = 0;
  try {
    sizing_field({{sdf, none}}, p);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no points"), std::string::npos) << e.what();
  }
  const Volume other = sample({11, 11, 12}, g, [](const Vec3& x) { return norm(x) - 3; });
  EXPECT_THROW(sizing_field({{sdf, ma}, {other, ma}}, p), InputError);
  const Volume positive = sample({11, 11, 11}, g, [](const Vec3& x) { return norm(x) + 1; });
  EXPECT_THROW(sizing_field({{positive, ma}}, p), InputError);
}

}  // namespace
}  // namespace pm
