#include "pm/field/distance.h"

#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <random>
#include <limits>
#include <cstring>
#include <functional>

#include "pm/base/error.h"

namespace pm {
namespace {

// A float volume with F(world position) at every node.
Volume sample(Dims d, const Geometry& g, const std::function<double(const Vec3&)>& F) {
  Volume v(VoxelType::f32, d, g);
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      for (std::size_t i = 0; i < d.nx; ++i)
        v.set(i, j, k, F(g.index_to_world(Vec3(double(i), double(j), double(k)))));
  return v;
}

// Central-difference gradient norm at an interior node (world units).
double grad_norm(const Volume& d, std::size_t i, std::size_t j, std::size_t k) {
  const Geometry& g = d.geometry();
  const double gx = (d.get(i + 1, j, k) - d.get(i - 1, j, k)) / (2 * g.spacing(0));
  const double gy = (d.get(i, j + 1, k) - d.get(i, j - 1, k)) / (2 * g.spacing(1));
  const double gz = (d.get(i, j, k + 1) - d.get(i, j, k - 1)) / (2 * g.spacing(2));
  return std::sqrt(gx * gx + gy * gy + gz * gz);
}

TEST(Distance, LinearFieldIsExact) {
  // A tilted plane: every foot point comes from an exact linear crossing.
  const Vec3 n = normalized(Vec3(0.3, -0.5, 0.8));
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-10, -10, -10));
  const Volume F = sample({21, 21, 21}, g, [&](const Vec3& x) { return dot(n, x) - 0.37; });
  const Volume d = signed_distance(F);
  double worst = 0;
  for (std::size_t c = 0; c < d.count(); ++c) {
    const Vec3 x = g.index_to_world(Vec3(double(c % 21), double((c / 21) % 21), double(c / 441)));
    const Vec3 foot = x - F.get(c) * n;  // the level set is only known inside the grid
    if (std::fabs(foot.x) < 9 && std::fabs(foot.y) < 9 && std::fabs(foot.z) < 9)
      worst = std::max(worst, std::fabs(d.get(c) - F.get(c)));
  }
  EXPECT_LT(worst, 0.02);  // voxel units; plane tilted against all three axes
}

TEST(Distance, GreySphereNearExactAndEikonal) {
  const double R = 9.3;
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-16, -16, -16));
  const Dims dims{33, 33, 33};
  const Volume F = sample(dims, g, [&](const Vec3& x) { return norm(x) - R; });
  const Volume d = signed_distance(F);
  double worst = 0, worst_grad = 0;
  for (std::size_t k = 1; k + 1 < dims.nz; ++k)
    for (std::size_t j = 1; j + 1 < dims.ny; ++j)
      for (std::size_t i = 1; i + 1 < dims.nx; ++i) {
        const double r = norm(g.index_to_world(Vec3(double(i), double(j), double(k))));
        worst = std::max(worst, std::fabs(d.get(i, j, k) - (r - R)));
        if (r > 2.5) worst_grad = std::max(worst_grad, std::fabs(grad_norm(d, i, j, k) - 1));
      }
  EXPECT_LT(worst, 0.1);       // voxels: the sphere is resolved with ~60 voxels around
  EXPECT_LT(worst_grad, 0.1);  // |∇d| = 1 away from the centre (the medial axis)
}

TEST(Distance, VoxelisedSphereMask) {
  const double R = 10;
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-20, -20, -20));
  const Dims dims{41, 41, 41};
  const Volume m = sample(dims, g, [&](const Vec3& x) { return norm(x) <= R ? 1.0 : 0.0; });
  const Volume d = mask_signed_distance(m);
  double worst_far = 0;
  for (std::size_t c = 0; c < d.count(); ++c) {
    const std::size_t i = c % 41, j = (c / 41) % 41, k = c / (41 * 41);
    const double r = norm(g.index_to_world(Vec3(double(i), double(j), double(k))));
    if (std::fabs(r - R) > 3) worst_far = std::max(worst_far, std::fabs(d.get(c) - (r - R)));
    ASSERT_EQ(d.get(c) < 0, m.get(c) != 0) << "sign at node " << c;
  }
  EXPECT_LT(worst_far, 1.0);  // within a voxel of |x| - R (staircase and half-voxel offset)
}

TEST(Distance, BoxMaskFacesHalfwayBetweenNodes) {
  Volume m(VoxelType::u8, {20, 20, 20}, Geometry::with_spacing(1, 1, 1));
  for (std::size_t k = 5; k <= 14; ++k)
    for (std::size_t j = 5; j <= 14; ++j)
      for (std::size_t i = 5; i <= 14; ++i) m.set(i, j, k, 255);
  const Volume d = mask_signed_distance(m);
  // Face x = 14.5: inside node 14, outside node 15; further out the distance grows by 1 a voxel.
  EXPECT_NEAR(d.get(14, 10, 10), -0.5, 1e-6);
  EXPECT_NEAR(d.get(15, 10, 10), 0.5, 1e-6);
  EXPECT_NEAR(d.get(19, 10, 10), 4.5, 1e-6);
  EXPECT_NEAR(d.get(10, 10, 10), -4.5, 1e-6);  // centre: 4.5 voxels to every face
  // Off a corner: about the distance to the corner point (14.5, 14.5, 14.5);
  // the corner is rounded by up to a quarter voxel.
  EXPECT_NEAR(d.get(18, 18, 18), std::sqrt(3.0) * 3.5, 0.25);
}

TEST(Distance, AnisotropicSpacingHonoured) {
  const double R = 7.1;  // only 3.5 voxels of the coarsest axis
  const Vec3 o(-10, -11, -9.5);
  const Geometry g = Geometry::with_spacing(0.5, 1.0, 2.0, o);
  const Dims dims{41, 23, 11};
  const Volume F = sample(dims, g, [&](const Vec3& x) { return 3.0 * (norm(x) - R); });  // |∇F| = 3
  const Volume d = signed_distance(F);
  double worst = 0;
  for (std::size_t k = 0; k < dims.nz; ++k)
    for (std::size_t j = 0; j < dims.ny; ++j)
      for (std::size_t i = 0; i < dims.nx; ++i) {
        const double r = norm(g.index_to_world(Vec3(double(i), double(j), double(k))));
        if (r > 2) worst = std::max(worst, std::fabs(d.get(i, j, k) - (r - R)));
      }
  EXPECT_LT(worst, 0.3);  // world units: 0.15 of the coarsest spacing (2)
  // Along x (spacing 0.5) the distance grows by 0.5 a node; along z (spacing 2) by 2.
  EXPECT_NEAR(d.get(39, 11, 5) - d.get(38, 11, 5), 0.5, 0.02);
  EXPECT_NEAR(d.get(20, 11, 10) - d.get(20, 11, 9), 2.0, 0.05);
}

TEST(Distance, NarrowBandMatchesInsideAndIsRoughOutside) {
  const double R = 9.3;
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-16, -16, -16));
  const Volume F = sample({33, 33, 33}, g, [&](const Vec3& x) { return norm(x) - R; });
  const Volume full = signed_distance(F);
  DistanceParams p;
  p.band = 2.5;
  const Volume nb = signed_distance(F, p);
  for (std::size_t c = 0; c < F.count(); ++c) {
    if (std::fabs(full.get(c)) <= p.band) ASSERT_EQ(nb.get(c), full.get(c)) << "node " << c;
    ASSERT_EQ(nb.get(c) < 0, full.get(c) < 0) << "node " << c;
    ASSERT_NEAR(nb.get(c), full.get(c), 1.0) << "node " << c;
  }
}

// The band limits only the outside: every inside node, however deep, keeps
// the accurate value; outside, the band's nodes do, and the farther ones stay
// correctly signed and within a voxel (as with the two-sided band).
TEST(Distance, OutsideOnlyBandKeepsTheWholeInsideExact) {
  const double R = 9.3;
  const Geometry g = Geometry::with_spacing(1, 1, 1, Vec3(-16, -16, -16));
  const Volume F = sample({33, 33, 33}, g, [&](const Vec3& x) { return norm(x) - R; });
  const Volume full = signed_distance(F);
  DistanceParams two, one;
  two.band = one.band = 2.5;
  one.band_outside_only = true;
  const Volume nb = signed_distance(F, two), ob = signed_distance(F, one);
  std::size_t deep_inside = 0, rough_two = 0, rough_one = 0;
  for (std::size_t c = 0; c < F.count(); ++c) {
    const double d = full.get(c);
    if (d < 0 || d <= one.band) ASSERT_EQ(ob.get(c), d) << "node " << c;
    ASSERT_EQ(ob.get(c) < 0, d < 0) << "node " << c;
    ASSERT_NEAR(ob.get(c), d, 1.0) << "node " << c;
    deep_inside += d < -one.band - 2;
    rough_two += d < 0 && nb.get(c) != d;
    rough_one += d > 0 && ob.get(c) != d;
  }
  // The test has teeth: the two-sided band does change deep inside nodes,
  // and the one-sided one the far outside ones.
  EXPECT_GT(deep_inside, 100u);
  EXPECT_GT(rough_two, 0u);
  EXPECT_GT(rough_one, 0u);
}

TEST(Distance, IsovalueAndSigns) {
  const Geometry g = Geometry::with_spacing(1, 1, 1);
  const Volume F = sample({12, 5, 5}, g, [](const Vec3& x) { return 10.0 * x.x; });
  DistanceParams p;
  p.iso = 43;  // plane at x = 4.3
  const Volume d = signed_distance(F, p);
  EXPECT_NEAR(d.get(4, 2, 2), -0.3, 1e-5);
  EXPECT_NEAR(d.get(5, 2, 2), 0.7, 1e-5);
  EXPECT_NEAR(d.get(11, 0, 4), 6.7, 1e-5);
  EXPECT_NEAR(d.get(0, 4, 0), -4.3, 1e-5);
}

TEST(Distance, NoCrossing) {
  const Volume F = sample({4, 4, 4}, Geometry{}, [](const Vec3& x) { return 1 + x.x; });
  try {
    signed_distance(F);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no voxels straddle the isovalue 0"), std::string::npos) << e.what();
  }
  DistanceParams p;
  p.allow_no_crossing = true;
  const Volume d = signed_distance(F, p);
  EXPECT_EQ(d.get(0), FLT_MAX);
  Volume empty(VoxelType::u8, {3, 3, 3});
  EXPECT_THROW(mask_signed_distance(empty), InputError);
}

TEST(Distance, RejectsShearedAxes) {
  Geometry g;
  g.directions.m[0][1] = 0.5;  // axis 1 leans on axis 0
  const Volume F = sample({4, 4, 4}, g, [](const Vec3& x) { return x.z - 1.5; });
  EXPECT_THROW(signed_distance(F), InputError);
}

TEST(Distance, OneVoxelMask) {
  Volume m(VoxelType::u8, {5, 5, 5}, Geometry::with_spacing(2, 2, 2));
  m.set(2, 2, 2, 1);
  const Volume d = mask_signed_distance(m);
  // Inside node: the plane through its three axis intercepts (h/2 each) is h/(2√3) away.
  EXPECT_NEAR(d.get(2, 2, 2), -2.0 / (2 * std::sqrt(3.0)), 1e-6);
  EXPECT_NEAR(d.get(3, 2, 2), 1.0, 1e-6);
  EXPECT_NEAR(d.get(4, 2, 2), 3.0, 1e-6);
}

}  // namespace
TEST(Distance, CandidateKernelsAgreeBitForBitWithTheBaselineCopies) {
  // The AVX2 copies of the candidate search (disc distances eight at a time,
  // the first strict minimum by a min-reduction) against the SSE2 / scalar
  // ones, bit for bit, for every count of candidates, points (m = 0) among
  // discs, exact ties, +infinity and NaN in the distances, and stale values
  // in the slots past the candidates.
  using detail::kDiscSlots;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-3.f, 3.f);
  int ties = 0;
  for (int round = 0; round < 400; ++round) {
    alignas(32) float p[3][kDiscSlots], m[3][kDiscSlots];
    for (int q = 0; q < kDiscSlots; ++q) {
      Vec3 nrm(u(rng), u(rng), u(rng));
      nrm = normalized(nrm);
      const bool point = q % 5 == 2;
      for (int a = 0; a < 3; ++a) {
        p[a][q] = u(rng);
        m[a][q] = point ? 0.f : float(nrm[a]);
      }
    }
    const int n = round % 28;
    const double x[3] = {u(rng), u(rng), u(rng)};
    alignas(32) float base[kDiscSlots], fast[kDiscSlots];
    detail::disc_distances(p, m, n, x, 0.6f, base, false);
    detail::disc_distances(p, m, n, x, 0.6f, fast, true);
    for (int q = 0; q < n; ++q) EXPECT_EQ(0, std::memcmp(&base[q], &fast[q], sizeof(float))) << round << " " << q;
    // Ties, infinities and NaN in the distances; junk past n.
    if (n > 3 && round % 3 == 0) {
      base[n - 1] = base[1];
      ++ties;
    }
    if (n > 4 && round % 4 == 1) base[0] = std::nanf("");
    if (round % 7 == 3)
      for (int q = 0; q < n; ++q) base[q] = std::numeric_limits<float>::infinity();
    for (int q = n; q < kDiscSlots; ++q) base[q] = -1.f;  // smaller than any distance: must be ignored
    float b0 = 0, b1 = 0;
    const int i0 = detail::first_strict_minimum(base, n, b0, false);
    const int i1 = detail::first_strict_minimum(base, n, b1, true);
    EXPECT_EQ(i0, i1) << round;
    EXPECT_EQ(0, std::memcmp(&b0, &b1, sizeof(float))) << round;
    if (i0 >= 0) EXPECT_EQ(b0, base[i0]);
  }
  EXPECT_GT(ties, 50);
}

}  // namespace pm
