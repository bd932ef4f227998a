#include "pm/field/materials.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>

#include "pm/base/error.h"
#include "pm/io/volume_io.h"
#include "test_util.h"

namespace pm {
namespace {

// 24^3 unit grid: label 1 for x < 11.5, label 2 for x > 11.5, and a 6^3 cube
// of label 5 at voxels 14..19 in every axis (inside label 2's half).
Volume three_labels(VoxelType t = VoxelType::u8) {
  Volume v(t, Dims{24, 24, 24});
  for (std::size_t k = 0; k < 24; ++k)
    for (std::size_t j = 0; j < 24; ++j)
      for (std::size_t i = 0; i < 24; ++i) {
        int l = i < 12 ? 1 : 2;
        if (i >= 14 && i <= 19 && j >= 14 && j <= 19 && k >= 14 && k <= 19) l = 5;
        v.set(i, j, k, l);
      }
  return v;
}

// Plane signed distance d = s * (x - x0) on a 16^3 grid with spacing h.
Volume plane(double x0, double s, double h = 0.5, Vec3 origin = {}) {
  Volume v(VoxelType::f32, Dims{16, 16, 16}, Geometry::with_spacing(h, h, h, origin));
  for (std::size_t k = 0; k < 16; ++k)
    for (std::size_t j = 0; j < 16; ++j)
      for (std::size_t i = 0; i < 16; ++i) v.set(i, j, k, s * (origin.x + h * double(i) - x0));
  return v;
}

TEST(Materials, FromLabelMap) {
  const MaterialSet ms = materials_from_labels(three_labels());
  ASSERT_EQ(ms.size(), 3u);
  EXPECT_EQ(ms.labels, (std::vector<int>{1, 2, 5}));
  EXPECT_EQ(ms.index_of(5), 2u);
  EXPECT_EQ(ms.index_of(7), 3u);
  EXPECT_DOUBLE_EQ(ms.resolution(), 1.0);
  // Every voxel node is labelled by its own voxel: the mask surfaces lie
  // halfway between nodes (level 0.5 of the trilinear mask, which bevels
  // edges), so a node is at least 0.5/sqrt(2) = 0.354 from every surface:
  // the own indicator is >= +0.354 and every other one <= -0.354 there.
  const Volume lv = three_labels();
  double f[3];
  for (std::size_t k = 0; k < 24; k += 1)
    for (std::size_t j = 0; j < 24; j += 3)
      for (std::size_t i = 0; i < 24; i += 1) {
        const Vec3 p{double(i), double(j), double(k)};
        const int want = int(lv.get(i, j, k));
        ASSERT_EQ(ms.label_at(p), want) << i << "," << j << "," << k;
        ms.indicators(p, f);
        for (std::size_t m = 0; m < 3; ++m) {
          if (ms.labels[m] == want) EXPECT_GE(f[m], 0.354 - 0.03);
          else EXPECT_LE(f[m], -0.354 + 0.03);
        }
      }
  // The 1|2 interface lies at x = 11.5: the two indicators agree there within
  // the distance transform's error (0.12 voxel) and Catmull-Rom's.
  ms.indicators({11.5, 6.0, 6.0}, f);
  EXPECT_NEAR(f[0], 0.0, 0.15);
  EXPECT_NEAR(f[1], 0.0, 0.15);
  EXPECT_EQ(ms.label_at({11.3, 6, 6}), 1);
  EXPECT_EQ(ms.label_at({11.7, 6, 6}), 2);
}

TEST(Materials, BoundedArgmaxIsTheArgmax) {
  // The bounds may only skip materials that cannot win: the same index at
  // random points, at the grid's nodes and outside the grid (no bounds).
  const MaterialSet ms = materials_from_labels(three_labels());
  const MaterialBounds b = material_bounds(ms);
  ASSERT_EQ(b.size(), 3u);
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-2, 25);
  for (int t = 0; t < 20000; ++t) {
    const Vec3 p{u(rng), u(rng), u(rng)};
    ASSERT_EQ(argmax_bounded(ms, b, p), ms.argmax(p)) << p.x << " " << p.y << " " << p.z;
  }
  const Volume grid = three_labels();
  const Volume am = argmax_labels(ms, grid);
  std::size_t disagree_with_map = 0;
  for (std::size_t k = 0; k < 24; ++k)
    for (std::size_t j = 0; j < 24; ++j)
      for (std::size_t i = 0; i < 24; ++i) {
        const Vec3 x{double(i), double(j), double(k)};
        ASSERT_EQ(am.data<std::int32_t>()[am.index(i, j, k)], ms.label_at(x));
        disagree_with_map += am.data<std::int32_t>()[am.index(i, j, k)] != int(grid.get(i, j, k));
      }
  EXPECT_EQ(disagree_with_map, 0u);  // at the nodes the argmax of the mask distances is the label map
}

// argmax_labels reads the samples where every field interpolates on the
// grid's own nodes, and evaluates the fields at near-ties: the labels equal
// label_at at every node. Values on a 0.5 lattice give many exact ties
// (resolved as argmax does: the smallest index); a grid shifted by a third
// of a voxel takes the general (bounded) path and also agrees.
TEST(Materials, ArgmaxLabelsAtNodesIsTheArgmax) {
  const Dims dims{13, 11, 9};
  const Geometry geo = Geometry::with_spacing(0.7, 1.3, 0.9, Vec3(-3.1, 2.2, 5.0));
  const std::string dir = test::temp_dir();
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<int> q(-6, 6);
  std::string spec;
  for (int m = 0; m < 4; ++m) {
    Volume v(VoxelType::f32, dims, geo);
    for (std::size_t c = 0; c < v.count(); ++c) v.set(c, 0.5 * q(rng));
    const std::string path = dir + "/m" + std::to_string(m) + ".nrrd";
    write_volume(v, path);
    spec += (m ? "," : "") + std::to_string(10 + m) + "=" + path;
  }
  const MaterialSet ms = load_materials(spec, KernelType::catmull_rom);
  const Volume grid(VoxelType::u8, dims, geo);
  const Volume am = argmax_labels(ms, grid);
  std::size_t ties = 0;
  double f[4];
  for (std::size_t k = 0; k < dims.nz; ++k)
    for (std::size_t j = 0; j < dims.ny; ++j)
      for (std::size_t i = 0; i < dims.nx; ++i) {
        const Vec3 x = geo.index_to_world(Vec3(double(i), double(j), double(k)));
        ASSERT_EQ(am.data<std::int32_t>()[am.index(i, j, k)], ms.label_at(x)) << i << "," << j << "," << k;
        ms.indicators(x, f);
        const double best = *std::max_element(f, f + 4);
        ties += std::count_if(f, f + 4, [&](double y) { return std::fabs(y - best) < 1e-6; }) > 1;
      }
  EXPECT_GT(ties, dims.count() / 10);  // the near-tie fallback was exercised
  const Volume shifted(VoxelType::u8, dims,
                       Geometry::with_spacing(0.7, 1.3, 0.9, Vec3(-3.1 + 0.7 / 3, 2.2, 5.0)));
  const Volume as = argmax_labels(ms, shifted);
  for (std::size_t k = 0; k < dims.nz; ++k)
    for (std::size_t j = 0; j < dims.ny; ++j)
      for (std::size_t i = 0; i < dims.nx; ++i)
        ASSERT_EQ(as.data<std::int32_t>()[as.index(i, j, k)],
                  ms.label_at(shifted.geometry().index_to_world(Vec3(double(i), double(j), double(k)))));
}

TEST(Materials, FromVolumesAndSigns) {
  const std::string dir = test::temp_dir();
  // material 3 is x < 3 (negative inside), material 4 is x > 3 given as an
  // indicator POSITIVE inside ("+path").
  write_volume(plane(3.0, 1.0), dir + "/a.nrrd");
  write_volume(plane(3.0, 1.0), dir + "/b.nrrd");  // positive for x > 3
  const MaterialSet ms = load_materials("3=" + dir + "/a.nrrd, 4=+" + dir + "/b.nrrd", KernelType::catmull_rom);
  ASSERT_EQ(ms.size(), 2u);
  EXPECT_EQ(ms.labels, (std::vector<int>{3, 4}));
  double f[2];
  ms.indicators({1.0, 2.0, 2.0}, f);
  EXPECT_NEAR(f[0], 2.0, 1e-5);   // -d = 3 - x
  EXPECT_NEAR(f[1], -2.0, 1e-5);  // +(x - 3)
  EXPECT_EQ(ms.label_at({2.9, 1, 1}), 3);
  EXPECT_EQ(ms.label_at({3.1, 1, 1}), 4);
  // Tie at x = 3 exactly: smallest index.
  EXPECT_EQ(ms.argmax({3.0, 1, 1}), 0u);
  const Box d = ms.domain();
  EXPECT_NEAR(d.hi.x, 7.5, 1e-12);
  EXPECT_NEAR(ms.resolution(), 0.5, 1e-12);
  // Derivatives of a '+' field are negated too.
  Vec3 g;
  ms.fields[1]->value_gradient({2.0, 2.0, 2.0}, g);
  EXPECT_NEAR(g.x, -1.0, 1e-5);
}

TEST(Materials, Errors) {
  const std::string dir = test::temp_dir();
  write_volume(plane(3.0, 1.0), dir + "/a.nrrd");
  write_volume(plane(3.0, -1.0), dir + "/b.nrrd");
  write_volume(plane(3.0, 1.0, 0.6), dir + "/spacing.nrrd");
  write_volume(plane(3.0, 1.0, 0.5, {1, 0, 0}), dir + "/origin.nrrd");
  const std::string a = dir + "/a.nrrd", b = dir + "/b.nrrd";
  EXPECT_THROW(load_materials("1=" + a), InputError);                      // fewer than 2
  EXPECT_THROW(load_materials("1=" + a + ",1=" + b), InputError);          // duplicate label
  EXPECT_THROW(load_materials("1=" + a + ",2=" + dir + "/spacing.nrrd"), InputError);
  EXPECT_THROW(load_materials("1=" + a + ",2=" + dir + "/origin.nrrd"), InputError);
  EXPECT_THROW(load_materials("x=" + a + ",2=" + b), UsageError);
  EXPECT_THROW(load_materials("1=" + a + ",,2=" + b), UsageError);
  EXPECT_THROW(load_materials(a + "," + b), UsageError);
  EXPECT_THROW(load_materials(""), UsageError);
  EXPECT_THROW(load_materials("1=" + dir + "/missing.nrrd,2=" + b), IoError);
  try {
    load_materials("1=" + a + ",2=" + dir + "/spacing.nrrd");
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("spacing.nrrd"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("same grid"), std::string::npos) << e.what();
  }
  // The volumes are read side by side, but the error is the first one in the
  // entries' order, whichever read finishes first: a missing file before a
  // grid mismatch, a mismatch before a later missing file; and a malformed
  // entry before any file is read.
  auto message = [&](const std::string& spec) -> std::string {
    try {
      load_materials(spec);
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  for (int round = 0; round < 5; ++round) {
    const std::string m1 = message("1=" + a + ",2=" + dir + "/missing2.nrrd,3=" + dir + "/spacing.nrrd");
    EXPECT_NE(m1.find("missing2.nrrd"), std::string::npos) << m1;
    const std::string m2 = message("1=" + a + ",2=" + dir + "/origin.nrrd,3=" + dir + "/missing3.nrrd");
    EXPECT_NE(m2.find("origin.nrrd"), std::string::npos) << m2;
    EXPECT_EQ(m2.find("missing3"), std::string::npos) << m2;
    const std::string m3 = message("1=" + a + ",2=" + dir + "/missing2.nrrd,3=" + dir + "/missing3.nrrd");
    EXPECT_NE(m3.find("missing2.nrrd"), std::string::npos) << m3;
  }
  EXPECT_THROW(load_materials("1=" + dir + "/missing.nrrd,2" + b), UsageError);
  // Label maps: one label, non-integer values, too many labels.
  Volume one(VoxelType::u8, Dims{4, 4, 4});
  EXPECT_THROW(materials_from_labels(one), InputError);
  Volume frac = three_labels(VoxelType::f32);
  frac.set(3, 3, 3, 1.5);
  try {
    materials_from_labels(frac);
    ADD_FAILURE() << "non-integer label map accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("(3,3,3) is 1.5"), std::string::npos) << e.what();
  }
  Volume many(VoxelType::u16, Dims{20, 20, 20});
  for (std::size_t c = 0; c < many.count(); ++c) many.set(c, double(c % 1000));
  EXPECT_THROW(materials_from_labels(many), InputError);
  // Float label maps with integral values are fine.
  EXPECT_EQ(materials_from_labels(three_labels(VoxelType::f32)).size(), 3u);
}

}  // namespace
}  // namespace pm
