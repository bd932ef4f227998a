// Volume packing (SPEC §7, issue #19): free particles inside a region,
// bounded by fixed boundary particles, and the interior sizing field that
// grows the surface's h inward by gradient limiting.
#include "pm/sample/volume_packing.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <vector>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/field/implicits.h"
#include "pm/volume/gradlimit.h"
#include "test_meshes.h"

namespace pm {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A field of the distance r = |x| to the origin, f(r) with f'(r) given.
class RadialField : public ScalarField {
 public:
  RadialField(std::function<double(double)> f, std::function<double(double)> df, double half)
      : f_(std::move(f)), df_(std::move(df)), half_(half) {}
  double value(const Vec3& x) const override { return f_(norm(x)); }
  double value_gradient(const Vec3& x, Vec3& g) const override {
    const double r = norm(x);
    g = r > 0 ? x * (df_(r) / r) : Vec3{};
    return f_(r);
  }
  double evaluate(const Vec3& x, Vec3& g, Mat3& h) const override {
    h = Mat3{};
    return value_gradient(x, g);
  }
  Box domain() const override {
    Box b;
    b.extend({-half_, -half_, -half_});
    b.extend({half_, half_, half_});
    return b;
  }
  double resolution() const override { return 1e-3; }
  std::string describe() const override { return "radial"; }

 private:
  std::function<double(double)> f_, df_;
  double half_;
};

// Nearest-neighbour distance of each point among `pts` (brute force).
std::vector<double> nearest(const std::vector<Vec3>& pts) {
  std::vector<double> d(pts.size(), 1e300);
  for (std::size_t i = 0; i < pts.size(); ++i)
    for (std::size_t j = 0; j < pts.size(); ++j)
      if (i != j) d[i] = std::min(d[i], norm(pts[i] - pts[j]));
  return d;
}

VolumePackParams params(double s) {
  VolumePackParams p;
  p.spacing = s;
  p.progress = false;
  return p;
}

TEST(VolumePacking, FillsABallInsideItsFixedBoundary) {
  set_verbosity(Verbosity::quiet);
  const double R = 1.0, s = 0.15;
  const auto ball = make_implicit("sphere:r=1");
  const Mesh surface = testing::icosphere(3, R);  // 642 vertices, edges 0.1 to 0.13
  const VolumePackResult r = pack_volume(*ball, 0.0, surface.vertices, params(s));
  EXPECT_EQ(r.fixed, surface.vertices.size());
  ASSERT_GT(r.points.size(), 100u);
  EXPECT_TRUE(r.converged);
  double clearance = 1e300;
  for (const Vec3& x : r.points) {
    EXPECT_LT(norm(x), R);  // F < 0: never outside
    for (const Vec3& b : surface.vertices) clearance = std::min(clearance, norm(x - b));
  }
  // No free particle sits on a fixed one (that would leave a sliver): the
  // pair energy's support is s, and equilibrium keeps neighbours near s.
  EXPECT_GT(clearance, 0.4 * s);
  std::vector<Vec3> all(surface.vertices);
  all.insert(all.end(), r.points.begin(), r.points.end());
  const std::vector<double> d = nearest(all);
  double nn = 0;
  std::size_t deep = 0;
  for (std::size_t i = surface.vertices.size(); i < all.size(); ++i)
    if (norm(all[i]) < R - 2 * s) nn += d[i], ++deep;
  nn /= double(deep);
  EXPECT_GT(nn, 0.7 * s);
  EXPECT_LT(nn, 1.3 * s);
  // A close packing at nearest distance nn has √2 / nn³ points per volume
  // (the densest; body-centred cubic, where the seeds start, 1.30 / nn³, a
  // loose random packing about 0.74 of the densest, and the mean nearest
  // distance exceeds the typical one): the deep ball r < R − 2s holds that
  // share within a factor 2.
  const double rd = R - 2 * s, est = 4.0 / 3 * kPi * rd * rd * rd * std::sqrt(2.0) / (nn * nn * nn);
  EXPECT_GT(double(deep), est / 2);
  EXPECT_LT(double(deep), est * 1.2);
}

TEST(VolumePacking, ARegionThinnerThanItsSpacingGetsNoParticles) {
  // A plate 0.1 thick (half-extent 0.05) packed at spacing 1: the seeds keep
  // 0.7 spacings from the fixed boundary particles, so none fits inside. The
  // region is left to the tetrahedralisation, with a warning, not an error
  // (the frog's bones at 2 mm).
  set_verbosity(Verbosity::quiet);
  const auto plate = make_implicit("box:a=1,b=1,c=0.05,r=0.01");
  std::vector<Vec3> fixed;
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j)
      for (double z : {-0.05, 0.05}) fixed.push_back({0.25 * i, 0.25 * j, z});
  const VolumePackResult r = pack_volume(*plate, 0.0, fixed, params(1.0));
  EXPECT_EQ(r.seeds, 0u);
  EXPECT_TRUE(r.points.empty());
  EXPECT_EQ(r.fixed, fixed.size());
  EXPECT_TRUE(r.converged);
}

TEST(VolumePacking, SameBytesForAnyThreadCount) {
  set_verbosity(Verbosity::quiet);
  const auto ball = make_implicit("sphere:r=1");
  const Mesh surface = testing::icosphere(2, 1.0);
  VolumePackResult a, b;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    a = pack_volume(*ball, 0.0, surface.vertices, params(0.2));
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    b = pack_volume(*ball, 0.0, surface.vertices, params(0.2));
  }
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    EXPECT_EQ(a.points[i].x, b.points[i].x);
    EXPECT_EQ(a.points[i].y, b.points[i].y);
    EXPECT_EQ(a.points[i].z, b.points[i].z);
  }
}

TEST(VolumePacking, EveryMaterialPackedInsideItsOwnRegion) {
  set_verbosity(Verbosity::quiet);
  // Material 1: the ball r < 0.5; material 2: the shell 0.5 < r < 1;
  // material 0 outside. Fields are distances, negative inside.
  const double half = 1.5;
  MaterialSet ms;
  ms.labels = {0, 1, 2};
  ms.fields = {std::make_shared<RadialField>([](double r) { return 1 - r; }, [](double) { return -1.0; }, half),
               std::make_shared<RadialField>([](double r) { return r - 0.5; }, [](double) { return 1.0; }, half),
               std::make_shared<RadialField>([](double r) { return std::max(r - 1, 0.5 - r); },
                                             [](double r) { return r - 1 > 0.5 - r ? 1.0 : -1.0; }, half)};
  const Mesh inner = testing::icosphere(2, 0.5), outer = testing::icosphere(3, 1.0);
  std::vector<Vec3> v(inner.vertices);
  v.insert(v.end(), outer.vertices.begin(), outer.vertices.end());
  std::vector<std::array<int, 3>> tris(inner.faces);
  std::vector<std::array<int, 2>> labels(inner.faces.size(), {1, 2});
  const int off = int(inner.vertices.size());
  for (const auto& f : outer.faces) {
    tris.push_back({f[0] + off, f[1] + off, f[2] + off});
    labels.push_back({0, 2});
  }
  const VolumePackResult r = pack_materials(ms, 0, v, tris, labels, params(0.15));
  std::size_t n1 = 0, n2 = 0;
  for (std::size_t i = 0; i < r.points.size(); ++i) {
    const double rad = norm(r.points[i]);
    ASSERT_NE(r.labels[i], 0);
    if (r.labels[i] == 1) {
      ++n1;
      EXPECT_LT(rad, 0.5);
    } else {
      ++n2;
      EXPECT_GT(rad, 0.5);
      EXPECT_LT(rad, 1.0);
    }
  }
  // Close packing at spacing ≈ s: the inner ball holds about
  // (4/3)π 0.5³ √2 / s³ ≈ 220 points, the shell about 7 times as many.
  EXPECT_GT(n1, 40u);
  EXPECT_GT(n2, 5 * n1 / 2);
  EXPECT_EQ(r.fixed, inner.vertices.size() + inner.vertices.size() + outer.vertices.size());
}

TEST(InteriorSizing, GrowsInwardAtTheGradientBoundAndIsCapped) {
  // h = 1 everywhere on a 41³ grid of 0.5; the boundary is a sphere of
  // radius 9. Only voxels within the band 1.0 of it keep h: elsewhere h
  // grows by delta per unit distance from the kept shell.
  Volume h(VoxelType::f32, Dims{41, 41, 41}, Geometry::with_spacing(0.5, 0.5, 0.5, {-10, -10, -10}));
  for (std::size_t i = 0; i < h.count(); ++i) h.set(i, 1.0);
  const Mesh sphere = testing::icosphere(4, 9.0);  // edges ≈ 0.5
  const double band = 1.0, delta = 0.2;
  const GradLimitResult r = interior_sizing(h, sphere.vertices, band, delta, 100);
  // At the centre the kept shell is 9 − band away (± half a voxel of
  // quantisation, plus the propagation's few % of delta × a voxel).
  EXPECT_NEAR(r.h.get(20, 20, 20), 1 + delta * (9 - band), delta * 0.5 + 0.02);
  EXPECT_DOUBLE_EQ(r.h.get(38, 20, 20), 1.0);  // x = 9: on the sphere
  EXPECT_LE(r.max_slope_ratio, 1 + 1e-5);
  const GradLimitResult capped = interior_sizing(h, sphere.vertices, band, delta, 2.0);
  EXPECT_DOUBLE_EQ(capped.h.get(20, 20, 20), 2.0);
  EXPECT_DOUBLE_EQ(capped.h.get(38, 20, 20), 1.0);
  // No cap given: the largest kept h (here 1) caps the interior.
  const GradLimitResult own = interior_sizing(h, sphere.vertices, band, delta, 0);
  EXPECT_DOUBLE_EQ(own.cap, 1.0);
  EXPECT_DOUBLE_EQ(own.h.get(20, 20, 20), 1.0);
  EXPECT_THROW(interior_sizing(h, sphere.vertices, 0, delta, 0), UsageError);
  EXPECT_THROW(interior_sizing(h, sphere.vertices, band, delta, -1), UsageError);
  EXPECT_THROW(interior_sizing(h, {Vec3{100, 100, 100}}, band, delta, 0), InputError);
}

}  // namespace
}  // namespace pm
