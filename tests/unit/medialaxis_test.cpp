#include "pm/volume/medialaxis.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "pm/base/error.h"
#include "pm/volume/tighten.h"

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

// Exact signed distance of the box [-a,a] x [-b,b] x [-c,c].
double box_sdf(const Vec3& x, double a, double b, double c) {
  const Vec3 q(std::fabs(x.x) - a, std::fabs(x.y) - b, std::fabs(x.z) - c);
  const Vec3 qp(std::max(q.x, 0.0), std::max(q.y, 0.0), std::max(q.z, 0.0));
  return norm(qp) + std::min(std::max(q.x, std::max(q.y, q.z)), 0.0);
}

const std::vector<double>& distances(const MedialAxisResult& r) { return r.points.vertex_scalars.at("distance"); }

TEST(MedialAxis, SphereCentre) {
  const double R = 10;
  const Vec3 c(0.31, -0.17, 0.44);  // off the grid nodes
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-15, -15, -15));
  const Volume sdf = sample({31, 31, 31}, g, [&](const Vec3& x) { return norm(x - c) - R; });
  const MedialAxisResult r = medial_axis(sdf);
  ASSERT_GT(r.points.vertices.size(), 0u);
  EXPECT_EQ(r.outer, 0u);  // a convex shape has no outer medial axis
  std::size_t near = 0;
  for (std::size_t i = 0; i < r.points.vertices.size(); ++i) {
    if (norm(r.points.vertices[i] - c) <= 1.0) ++near;
    EXPECT_NEAR(distances(r)[i], R, 0.5);
  }
  EXPECT_GE(double(near), 0.99 * double(r.points.vertices.size()));
}

TEST(MedialAxis, SlabMidPlane) {
  const double t = 8;  // thickness
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-8, -8, -9.3));
  const Volume sdf = sample({17, 17, 19}, g, [&](const Vec3& x) { return std::fabs(x.z) - t / 2; });
  const MedialAxisResult r = medial_axis(sdf);
  ASSERT_GT(r.points.vertices.size(), 100u);  // a sheet: about one point per column
  std::size_t on_plane = 0;
  for (std::size_t i = 0; i < r.points.vertices.size(); ++i) {
    if (std::fabs(r.points.vertices[i].z) < 0.25) ++on_plane;
    EXPECT_NEAR(distances(r)[i], t / 2, 0.25);
  }
  EXPECT_GE(double(on_plane), 0.99 * double(r.points.vertices.size()));
  // Only the nodes next to the mid-plane need foot points on the field.
  EXPECT_LE(r.nodes_refined, 17u * 17u * 4u);
}

TEST(MedialAxis, BoxPointsOnItsKnownPlanes) {
  const double a = 9, b = 6, c = 4.5;
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-12.2, -9.1, -7.3));
  const Volume sdf = sample({25, 19, 16}, g, [&](const Vec3& x) { return box_sdf(x, a, b, c); });
  MedialAxisParams p;
  const MedialAxisResult r = medial_axis(sdf, p);
  ASSERT_GT(r.inner, 100u);
  std::size_t on = 0;
  for (std::size_t i = 0; i < r.points.vertices.size(); ++i) {
    const Vec3& x = r.points.vertices[i];
    // On the inner MA the two nearest of the six faces are equally far.
    double f[6] = {a - x.x, a + x.x, b - x.y, b + x.y, c - x.z, c + x.z};
    std::sort(f, f + 6);
    if (f[1] - f[0] < 0.5) ++on;
    EXPECT_NEAR(distances(r)[i], f[0], 0.5);
  }
  EXPECT_GE(double(on), 0.99 * double(r.points.vertices.size()));
  EXPECT_LE(double(r.outer), 0.01 * double(r.inner));

}

TEST(MedialAxis, TightenedEllipsoidMask) {
  // Voxelised ellipsoid, tightened: its medial axis is the region of the plane
  // z = 0 inside the ellipse with semi-axes (a²-c²)/a and (b²-c²)/b.
  const double a = 20, b = 14, c = 9;
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-25, -20, -15));
  Volume mask(VoxelType::u8, {51, 41, 31}, g);
  for (std::size_t k = 0; k < 31; ++k)
    for (std::size_t j = 0; j < 41; ++j)
      for (std::size_t i = 0; i < 51; ++i) {
        const Vec3 x = g.index_to_world(Vec3(double(i), double(j), double(k)));
        mask.set(i, j, k, x.x * x.x / (a * a) + x.y * x.y / (b * b) + x.z * x.z / (c * c) <= 1 ? 1 : 0);
      }
  TightenParams tp;
  tp.radius = 1;
  const Volume sdf = tighten(mask, tp).distance;
  MedialAxisParams p;
  p.outside = false;
  const MedialAxisResult r = medial_axis(sdf, p);
  const double ea = (a * a - c * c) / a, eb = (b * b - c * c) / b;
  const double area = 3.14159265 * ea * eb;  // about one point per grid column through the sheet
  std::size_t on = 0;
  for (const Vec3& x : r.points.vertices)
    if (std::fabs(x.z) <= 1 && x.x * x.x / ((ea + 2) * (ea + 2)) + x.y * x.y / ((eb + 2) * (eb + 2)) <= 1) ++on;
  // The rest are short branches to what is left of the voxel staircase.
  EXPECT_GE(double(on), 0.85 * double(r.points.vertices.size()));
  EXPECT_GE(double(on), 0.7 * area);
  EXPECT_LE(double(r.points.vertices.size()), 1.5 * area);
}

TEST(MedialAxis, OneSideGivesThatSidesPointsOfBothForLessWork) {
  // Two balls of radius 6 whose centres are 15 apart: an inner MA at each
  // centre, an outer one on the plane between them. Each side alone must find
  // exactly the points `both` finds on it, in the same order (only the other
  // side's far nodes are skipped).
  const Vec3 c1(-7.5, 0.23, -0.31), c2(7.5, 0.23, -0.31);
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-17, -11, -11));
  const Volume sdf = sample({35, 23, 23}, g, [&](const Vec3& x) { return std::min(norm(x - c1), norm(x - c2)) - 6; });
  const MedialAxisResult all = medial_axis(sdf);
  ASSERT_GT(all.inner, 0u);
  ASSERT_GT(all.outer, 50u);
  for (const bool inner : {true, false}) {
    MedialAxisParams p;
    p.inside = inner;
    p.outside = !inner;
    const MedialAxisResult one = medial_axis(sdf, p);
    std::vector<Vec3> want;
    std::vector<double> want_d;
    for (std::size_t i = 0; i < all.points.vertices.size(); ++i) {
      const Vec3& x = all.points.vertices[i];
      const bool in = std::min(norm(x - c1), norm(x - c2)) < 6;
      if (in == inner) {
        want.push_back(x);
        want_d.push_back(distances(all)[i]);
      }
    }
    ASSERT_EQ(one.points.vertices.size(), want.size()) << (inner ? "inside" : "outside");
    EXPECT_EQ(inner ? one.inner : one.outer, want.size());
    for (std::size_t i = 0; i < want.size(); ++i) {
      EXPECT_EQ(one.points.vertices[i].x, want[i].x);
      EXPECT_EQ(one.points.vertices[i].y, want[i].y);
      EXPECT_EQ(one.points.vertices[i].z, want[i].z);
      EXPECT_EQ(distances(one)[i], want_d[i]);
    }
    // The inner side skips the outer nodes farther than 3.5 voxel diagonals;
    // the balls are too thin for the outer side to skip any inner ones.
    if (inner)
      EXPECT_LT(one.nodes_refined, all.nodes_refined);
    else
      EXPECT_EQ(one.nodes_refined, all.nodes_refined);
  }
}

TEST(MedialAxis, AnisotropicSpacing) {
  const double t = 6;
  const Geometry g = Geometry::with_spacing(2.0, 1.5, 0.5, Vec3(-10, -9, -5.1));
  const Volume sdf = sample({11, 13, 21}, g, [&](const Vec3& x) { return std::fabs(x.z) - t / 2; });
  const MedialAxisResult r = medial_axis(sdf);
  ASSERT_GT(r.points.vertices.size(), 20u);
  for (std::size_t i = 0; i < r.points.vertices.size(); ++i) {
    EXPECT_NEAR(r.points.vertices[i].z, 0.0, 0.25);
    EXPECT_NEAR(distances(r)[i], t / 2, 0.25);
  }
}

TEST(MedialAxis, RejectsMasksAndFieldsWithoutSurface) {
  Volume mask(VoxelType::u8, {6, 6, 6});
  mask.set(3, 3, 3, 1);
  try {
    medial_axis(mask);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected a signed distance volume (float), got a uint8 mask"),
              std::string::npos)
        << e.what();
  }
  Volume fmask = mask.converted(VoxelType::f32);
  EXPECT_THROW(medial_axis(fmask), InputError);
  const Volume pos = sample({6, 6, 6}, Geometry{}, [](const Vec3& x) { return 1 + x.x; });
  try {
    medial_axis(pos);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no zero crossing"), std::string::npos) << e.what();
  }
  MedialAxisParams p;
  p.cos_alpha = 1;
  EXPECT_THROW(medial_axis(pos, p), UsageError);
}

// Two balls of radius R in a box four times wider: the inner MA (their
// centres) lies R deep, the outer MA (their bisector plane, between them and
// far beyond them) reaches the box's faces.
const double kBallR = 4;
double two_balls(const Vec3& x) {
  return std::min(norm(x - Vec3(-5.1, 0.2, 0.3)), norm(x - Vec3(5.3, -0.1, 0.2))) - kBallR;
}
Volume two_balls_sdf() {
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-24, -24, -24));
  return sample({49, 49, 49}, g, two_balls);
}

TEST(MedialAxis, LfsBoundIsTwiceTheShallowSideDepth) {
  // The inside stays within the grid and is R deep (at a node within half a
  // voxel diagonal of the centre); the outside reaches the faces and does not count.
  const double diag = std::sqrt(3.0);
  const double b = medial_axis_lfs_bound(two_balls_sdf());
  EXPECT_LE(b, 2 * kBallR + 2 * diag + 1e-9);
  EXPECT_GE(b, 2 * (kBallR - diag / 2) + 2 * diag);
  // A slab whose inside and outside both reach the faces: no bound.
  const Volume slab = sample({11, 11, 13}, Geometry::with_spacing(1, 1, 1, Vec3(-5, -5, -6.3)),
                             [](const Vec3& x) { return std::fabs(x.z) - 3; });
  EXPECT_TRUE(std::isinf(medial_axis_lfs_bound(slab)));
}

TEST(MedialAxis, MaxDistanceKeepsExactlyTheNearPoints) {
  const Volume sdf = two_balls_sdf();
  const MedialAxisResult all = medial_axis(sdf);
  MedialAxisParams p;
  p.max_distance = 9;
  const MedialAxisResult near = medial_axis(sdf, p);
  ASSERT_GT(all.outer, near.outer + 100);  // the far bisector plane is gone
  EXPECT_EQ(near.inner, all.inner);          // the centres are kept
  // The kept points are the full run's points (bit for bit) of nodes with
  // |d| <= 9: a point lies within half a voxel diagonal of its node.
  const double half_diag = std::sqrt(3.0) / 2;
  std::size_t expected = 0;
  for (std::size_t i = 0; i < all.points.vertices.size(); ++i)
    if (distances(all)[i] <= p.max_distance - half_diag) ++expected;
  std::size_t found = 0;
  for (std::size_t i = 0; i < near.points.vertices.size(); ++i) {
    EXPECT_LE(distances(near)[i], p.max_distance + half_diag);
    const auto it = std::find(all.points.vertices.begin(), all.points.vertices.end(), near.points.vertices[i]);
    ASSERT_NE(it, all.points.vertices.end()) << "point " << i << " is not in the full run";
    EXPECT_EQ(distances(near)[i], distances(all)[std::size_t(it - all.points.vertices.begin())]);
    if (distances(near)[i] <= p.max_distance - half_diag) ++found;
  }
  EXPECT_EQ(found, expected);
  p.max_distance = 0;
  EXPECT_THROW(medial_axis(sdf, p), UsageError);
}

TEST(MedialAxis, MarkPoints) {
  const Volume like(VoxelType::f32, {5, 5, 5}, Geometry::with_spacing(2, 2, 2, Vec3(1, 1, 1)));
  const Volume m = mark_points(like, {Vec3(3.1, 4.9, 1.2), Vec3(100, 0, 0)});
  EXPECT_EQ(m.get(1, 2, 0), 1);
  double sum = 0;
  for (std::size_t c = 0; c < m.count(); ++c) sum += m.get(c);
  EXPECT_EQ(sum, 1);
}

}  // namespace
}  // namespace pm
