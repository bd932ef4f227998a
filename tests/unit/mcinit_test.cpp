#include "pm/volume/mcinit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "pm/base/error.h"

namespace pm {
namespace {

/// Distance field min_s (|x - c_s| - R_s) sampled on an n^3 grid.
Volume spheres(std::size_t n, const std::vector<std::pair<Vec3, double>>& balls, Geometry g = {}) {
  Volume v(VoxelType::f32, Dims{n, n, n}, g);
  for (std::size_t k = 0; k < n; ++k)
    for (std::size_t j = 0; j < n; ++j)
      for (std::size_t i = 0; i < n; ++i) {
        const Vec3 x = g.index_to_world(Vec3(double(i), double(j), double(k)));
        double d = 1e300;
        for (const auto& [c, r] : balls) d = std::min(d, norm(x - c) - r);
        v.set(i, j, k, d);
      }
  return v;
}

const Vec3 kCentre(15.3, 15.7, 16.1);
constexpr double kR = 9.0;

TEST(McInit, SphereSeedsLieOnTheSphere) {
  const Volume v = spheres(32, {{kCentre, kR}});
  McInitParams p;
  p.field = {KernelType::catmull_rom, KernelType::catmull_rom};
  p.project_steps = 0;
  const McInitResult raw = mc_seeds(v, p);
  EXPECT_EQ(raw.components, 1u);
  EXPECT_EQ(raw.projected, 0u);
  // Crossing edges of a surface of area A: A * mean(|nx| + |ny| + |nz|) = 1.5 A per voxel^2.
  EXPECT_NEAR(double(raw.crossings), 1.5 * 4 * M_PI * kR * kR, 0.05 * 1.5 * 4 * M_PI * kR * kR);
  ASSERT_EQ(raw.seeds.vertices.size(), raw.crossings);
  for (const Vec3& x : raw.seeds.vertices) ASSERT_LT(std::fabs(norm(x - kCentre) - kR), 1.0);

  // Projected onto the Catmull-Rom surface (interpolating: the sphere itself).
  p.project_steps = 6;
  const McInitResult cr = mc_seeds(v, p);
  EXPECT_EQ(cr.projected, cr.seeds.vertices.size());
  for (std::size_t s = 0; s < cr.seeds.vertices.size(); ++s) {
    const Vec3 x = cr.seeds.vertices[s];
    ASSERT_LT(std::fabs(norm(x - kCentre) - kR), 1e-3 * kR) << s;
    ASSERT_GT(dot(cr.seeds.normals[s], normalized(x - kCentre)), 0.99) << s;  // outwards
    ASSERT_NEAR(norm(cr.seeds.normals[s]), 1.0, 1e-9);
  }
  // The B-spline approximates: F = d + laplacian(d)/6 = d + 1/(3r) (unit
  // spacing), so its isosurface is the sphere of radius R - 1/(3R).
  p.field = {};
  const McInitResult bs = mc_seeds(v, p);
  for (const Vec3& x : bs.seeds.vertices) ASSERT_LT(std::fabs(norm(x - kCentre) - (kR - 1 / (3 * kR))), 1e-3 * kR);
  EXPECT_LT(bs.max_residual, 1e-4);
}

TEST(McInit, AnisotropicSpacingKeepsWorldUnits) {
  // F = |x - c|^2 - R^2 with spacing (0.8, 1.0, 1.3). Catmull-Rom reproduces
  // quadratics, so its surface is the sphere; the B-spline adds the second
  // moment s_a^2 / 3 per axis: radius sqrt(R^2 - (0.64 + 1 + 1.69) / 3).
  const Geometry g = Geometry::with_spacing(0.8, 1.0, 1.3, Vec3(-2, 1, 0.5));
  const Vec3 c(8.1, 13.6, 16.9);  // world box [-2,18] x [1,26] x [0.5,33]
  const double R = 7.5;
  Volume v(VoxelType::f64, Dims{26, 26, 26}, g);
  for (std::size_t k = 0; k < 26; ++k)
    for (std::size_t j = 0; j < 26; ++j)
      for (std::size_t i = 0; i < 26; ++i)
        v.set(i, j, k, norm2(g.index_to_world(Vec3(double(i), double(j), double(k))) - c) - R * R);
  McInitParams p;
  p.field = VolumeFieldParams::chapter5_mix();
  McInitResult r = mc_seeds(v, p);
  EXPECT_EQ(r.components, 1u);
  EXPECT_EQ(r.projected, r.seeds.vertices.size());
  for (const Vec3& x : r.seeds.vertices) ASSERT_NEAR(norm(x - c), R, 1e-4 * R);
  p.field = {};
  r = mc_seeds(v, p);
  const double rb = std::sqrt(R * R - (0.64 + 1.0 + 1.69) / 3);
  for (const Vec3& x : r.seeds.vertices) ASSERT_NEAR(norm(x - c), rb, 1e-4 * R);
}

TEST(McInit, EveryComponentIsSeededAndDecimationKeepsThem) {
  const Vec3 a(8, 8, 8), b(22.5, 21.5, 22);
  const Volume v = spheres(31, {{a, 4.0}, {b, 2.2}});
  McInitParams p;
  const McInitResult r = mc_seeds(v, p);
  EXPECT_EQ(r.components, 2u);
  const auto& comp = r.seeds.vertex_scalars.at("component");
  std::set<int> near_a, near_b;
  for (std::size_t s = 0; s < r.seeds.vertices.size(); ++s) {
    const Vec3 x = r.seeds.vertices[s];
    const bool in_a = std::fabs(norm(x - a) - 4.0) < 0.2, in_b = std::fabs(norm(x - b) - 2.2) < 0.3;
    ASSERT_TRUE(in_a || in_b) << x.x << " " << x.y << " " << x.z;
    (in_a ? near_a : near_b).insert(int(comp[s]));
  }
  ASSERT_EQ(near_a.size(), 1u);
  ASSERT_EQ(near_b.size(), 1u);
  EXPECT_NE(*near_a.begin(), *near_b.begin());

  p.decimate = 3;
  const McInitResult d = mc_seeds(v, p);
  EXPECT_EQ(d.components, 2u);
  EXPECT_EQ(d.crossings, r.crossings);
  EXPECT_LT(d.seeds.vertices.size() * 4, r.seeds.vertices.size());
  std::size_t on_b = 0;
  for (const Vec3& x : d.seeds.vertices) on_b += norm(x - b) < 3.0;
  EXPECT_GE(on_b, 4u);  // the small sphere (diameter < 2 blocks) is still seeded on all sides
  EXPECT_GT(d.seeds.vertices.size() - on_b, 20u);
}

TEST(McInit, BadInput) {
  Volume v(VoxelType::f32, Dims{4, 4, 4});
  v.set(1, 1, 1, 1.0);
  McInitParams p;
  p.iso = 5;
  try {
    mc_seeds(v, p);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "no surface: the isovalue 5 is outside the value range [0, 1]");
  }
  p.iso = 0;  // the minimum: nothing is below it
  try {
    mc_seeds(v, p);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no grid edge crosses"), std::string::npos) << e.what();
  }
  p.iso = 0.05;
  p.decimate = 0;
  EXPECT_THROW(mc_seeds(v, p), UsageError);
  EXPECT_THROW(mc_seeds(Volume(VoxelType::f32, Dims{4, 1, 4}), {}), InputError);
}

/// Labels 1, 2, 3 in three 120-degree sectors around the z axis through (c, c).
Volume y_shape(std::size_t n, std::size_t nz, double c) {
  Volume v(VoxelType::u8, Dims{n, n, nz});
  for (std::size_t k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < n; ++j)
      for (std::size_t i = 0; i < n; ++i) {
        const double ang = std::atan2(double(j) - c, double(i) - c) + M_PI;  // [0, 2pi]
        v.set(i, j, k, 1 + std::min(2, int(ang / (2 * M_PI / 3))));
      }
  return v;
}

TEST(McInit, JunctionsOfAYShape) {
  const Volume v = y_shape(14, 6, 6.5);
  const JunctionResult r = junction_seeds(v);
  using P = std::pair<std::int64_t, std::int64_t>;
  ASSERT_EQ(r.pairs.size(), 3u);
  EXPECT_GT(r.pairs.at(P{1, 2}), 20u);
  EXPECT_GT(r.pairs.at(P{1, 3}), 20u);
  EXPECT_GT(r.pairs.at(P{2, 3}), 20u);
  EXPECT_EQ(r.quadruples, 0u);
  EXPECT_GE(r.triples, 5u);  // at least one per cell layer
  const auto& jn = r.seeds.vertex_scalars.at("junction");
  const auto& la = r.seeds.vertex_scalars.at("label_a");
  const auto& lc = r.seeds.vertex_scalars.at("label_c");
  const auto& ld = r.seeds.vertex_scalars.at("label_d");
  std::set<int> layers;
  for (std::size_t s = 0; s < jn.size(); ++s) {
    const Vec3 x = r.seeds.vertices[s];
    if (jn[s] == 3) {
      // The triple line is the sector axis x = y = 6.5.
      EXPECT_LT(std::hypot(x.x - 6.5, x.y - 6.5), 1.5) << x.x << " " << x.y;
      EXPECT_EQ(la[s], 1);
      EXPECT_EQ(lc[s], 3);
      EXPECT_EQ(ld[s], -1);
      EXPECT_EQ(norm(r.seeds.normals[s]), 0.0);
      layers.insert(int(std::floor(x.z)));
    } else {
      ASSERT_EQ(jn[s], 2);
      EXPECT_EQ(lc[s], -1);
      EXPECT_DOUBLE_EQ(norm(r.seeds.normals[s]), 1.0);
      // Midpoint of a grid edge: exactly one coordinate is half-integer.
      int halves = 0;
      for (int a = 0; a < 3; ++a) halves += x[a] != std::floor(x[a]);
      EXPECT_EQ(halves, 1);
    }
  }
  EXPECT_EQ(layers.size(), 5u);  // every cell layer z = 0..4 has a triple seed

  const JunctionResult d = junction_seeds(v, {3});
  EXPECT_LT(d.seeds.vertices.size() * 3, r.seeds.vertices.size());
  EXPECT_EQ(d.pairs.size(), 3u);
  EXPECT_GE(d.triples, 2u);
}

TEST(McInit, QuadruplePointsAndBadLabels) {
  // Four quadrants around the z axis: 0, 1, 2, 3 (background 0 takes part).
  Volume v(VoxelType::i16, Dims{6, 6, 3});
  for (std::size_t k = 0; k < 3; ++k)
    for (std::size_t j = 0; j < 6; ++j)
      for (std::size_t i = 0; i < 6; ++i) v.set(i, j, k, (i < 3 ? 0 : 1) + (j < 3 ? 0 : 2));
  const JunctionResult r = junction_seeds(v);
  EXPECT_EQ(r.quadruples, 2u);  // the cells at x, y in [2, 3], one per z layer
  EXPECT_EQ(r.triples, 0u);
  EXPECT_EQ(r.pairs.size(), 4u);  // 0-1, 0-2, 1-3, 2-3 (0-3 and 1-2 only meet diagonally)

  Volume one(VoxelType::u8, Dims{3, 3, 3});
  EXPECT_THROW(junction_seeds(one), InputError);
  Volume grey(VoxelType::f32, Dims{3, 3, 3});
  grey.set(4, 0.5);
  EXPECT_THROW(junction_seeds(grey), InputError);
  Volume neg(VoxelType::i8, Dims{3, 3, 3});
  neg.set(4, -1);
  EXPECT_THROW(junction_seeds(neg), InputError);
}

}  // namespace
}  // namespace pm
