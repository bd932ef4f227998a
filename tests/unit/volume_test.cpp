#include "pm/base/volume.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "pm/base/error.h"

namespace pm {
namespace {

Geometry oblique_geometry() {
  // Rotation by 30 degrees about z, then 20 degrees about x, times spacings 0.5 0.75 1.25.
  const double a = M_PI / 6, b = M_PI / 9;
  Mat3 rz = Mat3::identity(), rx = Mat3::identity();
  rz[0][0] = std::cos(a); rz[0][1] = -std::sin(a); rz[1][0] = std::sin(a); rz[1][1] = std::cos(a);
  rx[1][1] = std::cos(b); rx[1][2] = -std::sin(b); rx[2][1] = std::sin(b); rx[2][2] = std::cos(b);
  Geometry g;
  g.directions = rx * rz * Mat3::diag(0.5, 0.75, 1.25);
  g.origin = {1.5, -2.25, 3.125};
  return g;
}

TEST(Volume, SetRoundsAndClampsIntegers) {
  Volume u8(VoxelType::u8, {4, 1, 1});
  u8.set(0, 1.4);
  u8.set(1, 1.6);
  u8.set(2, -3.0);
  u8.set(3, 300.0);
  EXPECT_EQ(u8.get(0), 1.0);
  EXPECT_EQ(u8.get(1), 2.0);
  EXPECT_EQ(u8.get(2), 0.0);
  EXPECT_EQ(u8.get(3), 255.0);
  u8.set(0, std::nan(""));
  EXPECT_EQ(u8.get(0), 0.0);

  Volume i8(VoxelType::i8, {3, 1, 1});
  i8.set(0, -200.0);
  i8.set(1, -1.7);
  i8.set(2, 127.4);
  EXPECT_EQ(i8.get(0), -128.0);
  EXPECT_EQ(i8.get(1), -2.0);
  EXPECT_EQ(i8.get(2), 127.0);

  Volume i16(VoxelType::i16, {2, 1, 1});
  i16.set(0, 40000.0);
  i16.set(1, -40000.0);
  EXPECT_EQ(i16.get(0), 32767.0);
  EXPECT_EQ(i16.get(1), -32768.0);

  Volume u64(VoxelType::u64, {2, 1, 1});
  u64.set(0, 1e30);
  u64.set(1, -5.0);
  EXPECT_EQ(u64.data<std::uint64_t>()[0], std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(u64.data<std::uint64_t>()[1], 0u);
}

TEST(Volume, FloatsKeepFractionsAndIndexingIsXFastest) {
  Volume f(VoxelType::f32, {3, 4, 5});
  EXPECT_EQ(f.count(), 60u);
  EXPECT_EQ(f.byte_size(), 240u);
  f.set(2, 1, 3, 0.1);
  EXPECT_EQ(f.index(2, 1, 3), 2u + 3u * (1u + 4u * 3u));
  EXPECT_FLOAT_EQ(static_cast<float>(f.get(2, 1, 3)), 0.1f);
  EXPECT_EQ(f.data<float>()[f.index(2, 1, 3)], 0.1f);
  EXPECT_THROW(f.data<double>(), Error);
  EXPECT_THROW(f.data<std::uint8_t>(), Error);
  f.set(0, -std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isinf(f.get(0)));
  EXPECT_THROW(require_finite(f, "x"), InputError);
}

TEST(Volume, ConvertedRoundsAndKeepsGeometry) {
  Volume f(VoxelType::f64, {5, 4, 3}, oblique_geometry());
  for (std::size_t i = 0; i < f.count(); ++i) f.set(i, 0.3 * double(i) - 5.0);
  const Volume u = f.converted(VoxelType::u8);
  EXPECT_EQ(u.type(), VoxelType::u8);
  EXPECT_TRUE(u.dims() == f.dims());
  for (std::size_t i = 0; i < f.count(); ++i) {
    const double want = std::clamp(std::nearbyint(0.3 * double(i) - 5.0), 0.0, 255.0);
    ASSERT_EQ(u.get(i), want) << "voxel " << i;
  }
  for (int r = 0; r < 3; ++r) {
    EXPECT_EQ(u.geometry().origin[r], f.geometry().origin[r]);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(u.geometry().directions[r][c], f.geometry().directions[r][c]);
  }
  const Volume back = u.converted(VoxelType::f32);
  EXPECT_EQ(value_range(back).hi, value_range(u).hi);
  EXPECT_GT(value_range(u).hi, 0.0);
}

TEST(Volume, WorldBoundsOfAxisAlignedAndObliqueGrids) {
  Volume v(VoxelType::u8, {5, 4, 3}, Geometry::with_spacing(0.5, 2.0, 3.0, {1, 2, 3}));
  Box b = v.world_bounds();
  EXPECT_DOUBLE_EQ(b.lo.x, 1.0);
  EXPECT_DOUBLE_EQ(b.hi.x, 1.0 + 4 * 0.5);
  EXPECT_DOUBLE_EQ(b.lo.y, 2.0);
  EXPECT_DOUBLE_EQ(b.hi.y, 2.0 + 3 * 2.0);
  EXPECT_DOUBLE_EQ(b.hi.z, 3.0 + 2 * 3.0);

  // Flipped x axis: the box still spans both ends.
  Geometry flipped = Geometry::with_spacing(-1.0, 1.0, 1.0, {10, 0, 0});
  Volume f(VoxelType::u8, {5, 4, 3}, flipped);
  EXPECT_DOUBLE_EQ(f.world_bounds().lo.x, 6.0);
  EXPECT_DOUBLE_EQ(f.world_bounds().hi.x, 10.0);

  Volume o(VoxelType::u8, {5, 4, 3}, oblique_geometry());
  b = o.world_bounds();
  for (int c = 0; c < 8; ++c) {
    const Vec3 ijk((c & 1) ? 4 : 0, (c & 2) ? 3 : 0, (c & 4) ? 2 : 0);
    const Vec3 p = o.geometry().index_to_world(ijk);
    EXPECT_TRUE(b.contains(p)) << "corner " << c;
  }
  // The box is tight: some corner reaches each face.
  double max_x = -1e300;
  for (int c = 0; c < 8; ++c)
    max_x = std::max(max_x, o.geometry().index_to_world({(c & 1) ? 4.0 : 0.0, (c & 2) ? 3.0 : 0.0, (c & 4) ? 2.0 : 0.0}).x);
  EXPECT_DOUBLE_EQ(b.hi.x, max_x);
}

TEST(Volume, WorldToIndexInvertsIndexToWorld) {
  const Geometry g = oblique_geometry();
  for (int t = 0; t < 20; ++t) {
    const Vec3 ijk(0.37 * t, 2.0 - 0.11 * t, 0.05 * t * t);
    const Vec3 back = g.world_to_index(g.index_to_world(ijk));
    EXPECT_NEAR(back.x, ijk.x, 1e-12);
    EXPECT_NEAR(back.y, ijk.y, 1e-12);
    EXPECT_NEAR(back.z, ijk.z, 1e-12);
  }
  EXPECT_NEAR(g.spacing(0), 0.5, 1e-12);
  EXPECT_NEAR(g.spacing(1), 0.75, 1e-12);
  EXPECT_NEAR(g.spacing(2), 1.25, 1e-12);
  EXPECT_FALSE(g.axis_aligned());
  EXPECT_TRUE(Geometry::with_spacing(1, 2, 3).axis_aligned());
}

// Padding keeps every voxel at its world position (oblique grid too), fills
// the margin with the value, and keeps the type.
TEST(Volume, PaddedKeepsWorldPositions) {
  Volume v(VoxelType::i16, {3, 4, 2}, oblique_geometry());
  for (std::size_t i = 0; i < v.count(); ++i) v.set(i, double(i) - 7);
  const Volume p = padded(v, 2, 99);
  EXPECT_EQ(p.type(), VoxelType::i16);
  EXPECT_EQ(p.dims().nx, 7u);
  EXPECT_EQ(p.dims().ny, 8u);
  EXPECT_EQ(p.dims().nz, 6u);
  for (std::size_t k = 0; k < 2; ++k)
    for (std::size_t j = 0; j < 4; ++j)
      for (std::size_t i = 0; i < 3; ++i) {
        EXPECT_EQ(p.get(i + 2, j + 2, k + 2), v.get(i, j, k));
        const Vec3 a = v.geometry().index_to_world(Vec3(double(i), double(j), double(k)));
        const Vec3 b = p.geometry().index_to_world(Vec3(double(i + 2), double(j + 2), double(k + 2)));
        EXPECT_NEAR(norm(a - b), 0.0, 1e-12);
      }
  std::size_t margin = 0;
  for (std::size_t i = 0; i < p.count(); ++i) margin += p.get(i) == 99;
  EXPECT_EQ(margin, p.count() - v.count());
}

TEST(Volume, ZeroSizeAxisAndSingularGeometryThrow) {
  EXPECT_THROW(Volume(VoxelType::f32, {0, 4, 3}), InputError);
  EXPECT_THROW(Volume(VoxelType::f32, {5, 0, 3}), InputError);
  EXPECT_THROW(Volume(VoxelType::f32, {5, 4, 0}), InputError);
  try {
    Volume(VoxelType::u8, {5, 0, 3});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("zero-size axis"), std::string::npos) << e.what();
  }
  Geometry singular;
  singular.directions = Mat3::diag(1.0, 0.0, 1.0);
  EXPECT_THROW(Volume(VoxelType::f32, {2, 2, 2}, singular), InputError);
  const std::size_t huge = std::size_t(1) << 40;
  EXPECT_THROW(Volume(VoxelType::f64, {huge, huge, huge}), InputError);
  EXPECT_TRUE(Volume().empty());
}

TEST(Volume, TypeNames) {
  for (VoxelType t : {VoxelType::u8, VoxelType::i8, VoxelType::u16, VoxelType::i16, VoxelType::u32, VoxelType::i32,
                      VoxelType::u64, VoxelType::i64, VoxelType::f32, VoxelType::f64})
    EXPECT_EQ(parse_voxel_type(voxel_type_name(t)), t);
  EXPECT_EQ(voxel_size(VoxelType::i16), 2u);
  EXPECT_EQ(voxel_size(VoxelType::u64), 8u);
  EXPECT_FALSE(is_integer(VoxelType::f32));
  EXPECT_TRUE(is_integer(VoxelType::i8));
  EXPECT_THROW(parse_voxel_type("complex"), UsageError);
}

TEST(Volume, SmallestIntegerTypeHoldsEveryValue) {
  auto with = [](VoxelType t, double lo, double hi) {
    Volume v(t, Dims{2, 1, 1});
    v.set(0, lo);
    v.set(1, hi);
    return smallest_integer_type(v);
  };
  EXPECT_EQ(with(VoxelType::i32, 0, 255), VoxelType::u8);
  EXPECT_EQ(with(VoxelType::i32, 0, 256), VoxelType::u16);
  EXPECT_EQ(with(VoxelType::u16, 0, 65535), VoxelType::u16);
  EXPECT_EQ(with(VoxelType::i32, 0, 65536), VoxelType::u32);
  EXPECT_EQ(with(VoxelType::i32, -1, 127), VoxelType::i8);
  EXPECT_EQ(with(VoxelType::i32, -1, 128), VoxelType::i16);
  EXPECT_EQ(with(VoxelType::i32, -32769, 0), VoxelType::i32);
  EXPECT_EQ(with(VoxelType::i64, -1, 4294967295.0), VoxelType::i64);  // nothing smaller holds both
  // Converting to it keeps every value.
  Volume v(VoxelType::i32, Dims{3, 1, 1});
  v.set(0, 0);
  v.set(1, 4);
  v.set(2, 200);
  const Volume c = v.converted(smallest_integer_type(v));
  EXPECT_EQ(c.type(), VoxelType::u8);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(c.get(i), v.get(i));
  EXPECT_THROW(smallest_integer_type(Volume(VoxelType::f32, Dims{2, 2, 2})), InputError);
}

TEST(Volume, WorldSignsMapRasAndLpsBothWays) {
  Geometry g = Geometry::with_spacing(0.5, 2, 3, {10, 0, 30});
  g.directions[0][1] = 0.25;
  const Geometry r = with_world_signs(g, {-1, -1, 1});
  EXPECT_EQ(r.origin.x, -10.0);
  EXPECT_EQ(r.directions[0][0], -0.5);
  EXPECT_EQ(r.directions[0][1], -0.25);
  EXPECT_EQ(r.directions[1][1], -2.0);
  EXPECT_EQ(r.directions[2][2], 3.0);
  // A negated 0 is +0 (so headers never say "-0").
  EXPECT_FALSE(std::signbit(r.origin.y));
  EXPECT_FALSE(std::signbit(r.directions[1][0]));
  // The same voxel is at the mirrored point; twice is the identity.
  const Vec3 p = g.index_to_world({1, 2, 3}), q = r.index_to_world({1, 2, 3});
  EXPECT_EQ(q.x, ras_from_lps(p).x);
  EXPECT_EQ(q.y, ras_from_lps(p).y);
  EXPECT_EQ(q.z, p.z);
  const Geometry back = with_world_signs(r, {-1, -1, 1});
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(back.origin[i], g.origin[i]);
    for (int j = 0; j < 3; ++j) EXPECT_EQ(back.directions[i][j], g.directions[i][j]);
  }
}

TEST(Volume, PositiveStepsKeepWorldPositions) {
  Geometry g = Geometry::with_spacing(1, 2, 3, {5, 6, 7});
  g.directions[1][1] = -2;
  Volume v(VoxelType::i16, Dims{3, 4, 2}, g);
  for (std::size_t i = 0; i < v.count(); ++i) v.set(i, double(i));
  const Volume p = with_positive_steps(v, "t");
  EXPECT_EQ(p.geometry().directions[1][1], 2.0);
  EXPECT_EQ(p.geometry().origin.y, 6.0 - 2 * 3);
  for (std::size_t k = 0; k < 2; ++k)
    for (std::size_t j = 0; j < 4; ++j)
      for (std::size_t i = 0; i < 3; ++i) {
        const Vec3 w = v.geometry().index_to_world(Vec3(double(i), double(j), double(k)));
        const Vec3 q = p.geometry().world_to_index(w);
        ASSERT_EQ(p.get(std::size_t(std::lround(q.x)), std::size_t(std::lround(q.y)), std::size_t(std::lround(q.z))),
                  v.get(i, j, k));
      }
  // Nothing flipped: the same volume; oblique: refused.
  const Volume same = with_positive_steps(Volume(VoxelType::u8, Dims{2, 2, 2}), "t");
  EXPECT_EQ(same.geometry().directions[0][0], 1.0);
  Geometry ob = Geometry::with_spacing(1, 1, 1);
  ob.directions[0][1] = 0.5;
  EXPECT_THROW(with_positive_steps(Volume(VoxelType::u8, Dims{2, 2, 2}, ob), "t"), InputError);
}

}  // namespace
}  // namespace pm
