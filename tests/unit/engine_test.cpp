// The one particle engine with the constraints prepared for the next
// chapters: a particle state that is not a world point (element id +
// reference coordinates of a mapped element), the volume interior F < c
// (12 ideal neighbours), and typed particles whose type pair scales α_ij.
#include "pm/sample/engine.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "pm/sample/element_constraint.h"
#include "pm/sample/surface_constraint.h"
#include "pm/sample/volume_constraint.h"
#include "test_fields.h"

namespace pm {
namespace {

constexpr double kPi = 3.14159265358979323846;

using test::Ball;

EngineParams quiet_params(double s) {
  EngineParams p;
  p.spacing = s;
  p.progress = false;
  return p;
}

// Distances from every point to its nearest neighbour (brute force).
std::vector<double> nearest(const std::vector<Vec3>& x) {
  std::vector<double> d(x.size(), 1e300);
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = 0; j < x.size(); ++j)
      if (i != j) d[i] = std::min(d[i], norm(x[i] - x[j]));
  return d;
}
double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s / double(v.size());
}

template <class C>
void seed_points(ParticleEngine<C>& e, const std::vector<Vec3>& xs, const typename C::Point& like) {
  std::vector<typename ParticleEngine<C>::Candidate> cands;
  for (const Vec3& x : xs) cands.push_back({x, like, 0});
  std::vector<typename C::Point> placed;
  std::vector<char> ok;
  e.place_many(cands, engine_constants::kPlaceSteps, {}, placed, ok);
  for (std::size_t i = 0; i < xs.size(); ++i)
    if (ok[i]) e.add(placed[i]);
}

// --- element id + reference coordinates ----------------------------------------

// A trilinear hexahedron: the unit cube stretched to 2 × 1.5 × 1 and sheared
// (top face shifted by 0.3 in x, one corner pulled out by 0.2), so that the
// reference sphere |u - (½,½,½)| = 0.35 maps to a distorted closed surface.
TrilinearElements sheared_hex() {
  std::array<Vec3, 8> c;
  for (int k = 0; k < 8; ++k) {
    const double i = k & 1, j = (k >> 1) & 1, l = (k >> 2) & 1;
    c[std::size_t(k)] = {2 * i + 0.3 * l, 1.5 * j, 1 * l};
  }
  c[7] += Vec3{0.2, 0.2, 0.2};
  return TrilinearElements({c});
}

// The bins' sub-cells: for points on a sphere (the surface case the
// sub-cells are for) and balls of several radii around points near it,
// the ranges visit_box gives over the 3x3x3 block hold every point within
// the radius, each once, and cover the bin's points exactly once when the
// box spans the bin. Bins keep their points whatever the sub-cell count.
TEST(EngineBins, SubCellsVisitEveryPointWithinTheBox) {
  std::vector<Vec3> x;
  const int n = 4000;
  for (int k = 0; k < n; ++k) {  // a Fibonacci sphere of radius 3
    const double z = 1 - (2 * k + 1.0) / n, r = std::sqrt(1 - z * z), a = k * 2.399963229728653;
    x.push_back(3.0 * Vec3{r * std::cos(a), r * std::sin(a), z});
  }
  const std::vector<char> all;
  SampleBins one, three;
  one.build(x, 1.0, all, 1);
  three.build(x, 1.0, all, 3);
  ASSERT_EQ(one.cells(), three.cells());
  std::vector<Vec3> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) y[i] = x[three.order()[i]];
  for (std::size_t c = 0; c < three.cells(); ++c) {
    EXPECT_EQ(one.end(c) - one.begin(c), three.end(c) - three.begin(c));
    std::size_t seen = 0;
    three.visit_box(c, y[three.begin(c)], 10.0, [&](std::uint32_t b, std::uint32_t e) {
      EXPECT_GE(b, three.begin(c));
      EXPECT_LE(e, three.end(c));
      seen += e - b;
    });
    EXPECT_EQ(seen, std::size_t(three.end(c) - three.begin(c)));
  }
  std::size_t fewer = 0, total = 0;
  for (std::size_t i = 0; i < y.size(); i += 37)
    for (double r : {0.05, 0.2, 0.45}) {
      const Vec3 p = y[i] * (1 + 0.02 * r);
      std::int32_t block[27];
      ASSERT_TRUE(three.block_of(p, block));
      std::vector<int> hits(y.size(), 0);
      std::size_t scanned = 0;
      for (int k = 0; k < 27; ++k)
        if (block[k] >= 0)
          three.visit_box(std::size_t(block[k]), p, r, [&](std::uint32_t b, std::uint32_t e) {
            for (std::uint32_t q = b; q < e; ++q) ++hits[q];
            scanned += e - b;
          });
      std::size_t in_block = 0;
      for (int k = 0; k < 27; ++k)
        if (block[k] >= 0) in_block += three.end(std::size_t(block[k])) - three.begin(std::size_t(block[k]));
      for (std::size_t q = 0; q < y.size(); ++q) {
        EXPECT_LE(hits[q], 1);
        if (norm(y[q] - p) <= r) EXPECT_EQ(hits[q], 1) << "point " << q << " within " << r;
      }
      fewer += scanned < in_block;
      ++total;
    }
  EXPECT_GT(fewer, total / 2);  // the sub-cells do prune
}

// Points on the sub-cell faces (a lattice of a third of the bin width, the
// bin corner at a lattice point) and balls whose boxes end exactly on faces:
// rounding in the sub-cell coordinates of a box never drops a point on its
// face, and the ranges stay in increasing order (a gather's candidate order).
TEST(EngineBins, SubCellsKeepPointsOnTheirFaces) {
  std::vector<Vec3> x;
  for (int k = 0; k < 13; ++k)
    for (int j = 0; j < 13; ++j)
      for (int i = 0; i < 13; ++i) x.push_back(Vec3{i / 3.0, j / 3.0, k / 3.0} + Vec3{0.1, -0.2, 0.3});
  const std::vector<char> all;
  SampleBins bins;
  bins.build(x, 1.0, all, 3);
  std::vector<Vec3> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) y[i] = x[bins.order()[i]];
  std::size_t checked = 0;
  for (std::size_t i = 0; i < y.size(); i += 7)
    for (double r : {1 / 3.0, 2 / 3.0, 1.0}) {
      std::int32_t block[27];
      if (!bins.block_of(y[i], block)) continue;
      std::vector<int> hits(y.size(), 0);
      for (int k = 0; k < 27; ++k) {
        if (block[k] < 0) continue;
        std::uint32_t last = 0;
        bins.visit_box(std::size_t(block[k]), y[i], r, [&](std::uint32_t b, std::uint32_t e) {
          EXPECT_GE(b, last);
          last = e;
          for (std::uint32_t q = b; q < e; ++q) ++hits[q];
        });
      }
      for (std::size_t q = 0; q < y.size(); ++q) {
        const Vec3 d = y[q] - y[i];
        // Within the box (up to the lattice's own rounding) and in the block.
        if (std::fabs(d.x) <= r + 1e-12 && std::fabs(d.y) <= r + 1e-12 && std::fabs(d.z) <= r + 1e-12 &&
            norm(d) <= r) {
          EXPECT_EQ(hits[q], 1) << "point " << q << " at " << norm(d) << " of point " << i << ", r " << r;
          ++checked;
        }
      }
    }
  EXPECT_GT(checked, 1000u);
}

// The quadratic step control on an exact parabola e(λ) = -gλ + cλ²
// (g = 2, c = 1/2, minimum at λ = g/2c = 2): one trial, at any step, finds
// the minimiser, and the next step is kStepOverRelax times it within the
// bounds.
TEST(EngineStep, QuadraticStepFindsTheMinimumOfAParabola) {
  using engine_constants::kStepOverRelax;
  const double g = 2, c = 0.5;
  const auto de = [&](double l) { return -g * l + c * l * l; };
  for (double l : {0.25, 1.0, 3.0, 6.0})
    EXPECT_NEAR(quadratic_step(l, g, de(l), 1e-9, 1e9), kStepOverRelax * 2, 1e-12) << "trial step " << l;
  EXPECT_DOUBLE_EQ(quadratic_step(1.0, g, de(1.0), 0.1, 2.5), 2.5);  // clamped above
  EXPECT_DOUBLE_EQ(quadratic_step(6.0, g, de(6.0), 4.0, 5.0), 4.0);  // clamped below
  // A concave stretch (the energy fell faster than the slope says) has no
  // minimum: the largest step allowed.
  EXPECT_DOUBLE_EQ(quadratic_step(1.0, g, -3.0, 0.1, 10.0), 10.0);
  // A linear energy (c = 0) too.
  EXPECT_DOUBLE_EQ(quadratic_step(1.0, g, -2.0, 0.1, 10.0), 10.0);
}

TEST(EngineElement, TrilinearJacobianMatchesFiniteDifferences) {
  const TrilinearElements hex = sheared_hex();
  const Vec3 u{0.3, 0.6, 0.8};
  Mat3 j;
  hex.world(0, u, &j);
  const double h = 1e-6;
  for (int a = 0; a < 3; ++a) {
    Vec3 up = u, um = u;
    up[a] += h;
    um[a] -= h;
    const Vec3 d = (hex.world(0, up, nullptr) - hex.world(0, um, nullptr)) / (2 * h);
    for (int r = 0; r < 3; ++r) EXPECT_NEAR(j.m[r][a], d[r], 1e-8);
  }
  // Corners map to corners.
  EXPECT_NEAR(norm(hex.world(0, {1, 1, 1}, nullptr) - Vec3{2.5, 1.7, 1.2}), 0, 1e-15);
}

// World area of the image of the reference sphere: ∫ det J |J⁻ᵀ n| dA_ref
// by the midpoint rule in (θ, φ).
double mapped_sphere_area(const ElementMap& m, const Vec3& c, double r) {
  const int nt = 400, np = 800;
  double area = 0;
  for (int a = 0; a < nt; ++a)
    for (int b = 0; b < np; ++b) {
      const double t = kPi * (a + 0.5) / nt, p = 2 * kPi * (b + 0.5) / np;
      const Vec3 n{std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
      Mat3 j;
      m.world(0, c + n * r, &j);
      const double da = r * r * std::sin(t) * (kPi / nt) * (2 * kPi / np);
      area += determinant(j) * norm(transpose(inverse(j)) * n) * da;
    }
  return area;
}

TEST(EngineElement, ParticlesInReferenceSpacePackTheMappedSurfaceInWorldUnits) {
  const TrilinearElements hex = sheared_hex();
  const Vec3 c{0.5, 0.5, 0.5};
  const double r = 0.35, s = 0.12;
  const Ball g(c, r, 1.0);
  const ElementConstraint ec(hex, g);
  ParticleEngine<ElementConstraint> e(ec, quiet_params(s));
  // Seeds: reference points on a coarse lattice, projected in reference space.
  for (int k = 0; k < 40; ++k) {
    const double z = 1 - 2 * (k + 0.5) / 40, q = std::sqrt(1 - z * z), ph = 2.4 * k;
    ElementConstraint::Point p;
    Probe pr;
    ASSERT_TRUE(ec.place_reference(0, c + Vec3{q * std::cos(ph), q * std::sin(ph), z} * (0.8 * r), 20, p, pr));
    e.add(p);
  }
  const auto lr = e.relax("element", false);
  EXPECT_TRUE(lr.converged);
  std::vector<Vec3> xs;
  for (const auto& q : e.particles()) {
    // The state is the truth: the world point and Jacobian follow from it.
    const ElementConstraint::State& st = q.p.s;
    EXPECT_EQ(st.element, 0);
    EXPECT_NEAR(norm(st.u - c), r, 1e-8);
    Mat3 j;
    const Vec3 x = hex.world(0, st.u, &j);
    EXPECT_EQ(x, q.p.x);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) EXPECT_EQ(j.m[a][b], st.jacobian.m[a][b]);
    // The normal is the world normal of the mapped surface: orthogonal to
    // the images J t of reference tangents t.
    const Vec3 nr = normalized(st.u - c);
    Vec3 t1, t2;
    tangent_basis(nr, t1, t2);
    EXPECT_NEAR(dot(q.p.n, j * t1), 0, 1e-9);
    EXPECT_NEAR(dot(q.p.n, j * t2), 0, 1e-9);
    xs.push_back(q.p.x);
  }
  // Count in the population's stable band around the hexagonal estimate of
  // the WORLD area (0.86-1.27, pm/sample/particles.h), and neighbours at the
  // world spacing: the nearest neighbour runs ~10% short of s (SPEC §3).
  const double area = mapped_sphere_area(hex, c, r);
  const double hex_count = area / (std::sqrt(3.0) / 2 * s * s);
  EXPECT_GT(double(xs.size()), 0.8 * hex_count) << "area " << area;
  EXPECT_LT(double(xs.size()), 1.3 * hex_count) << "area " << area;
  const double nn = mean(nearest(xs));
  EXPECT_GT(nn, 0.75 * s);
  EXPECT_LT(nn, 1.05 * s);
}

TEST(EngineElement, WorldPointsOutsideTheElementAreRejected) {
  const TrilinearElements hex = sheared_hex();
  const Ball g({0.5, 0.5, 0.5}, 0.35, 1.0);
  const ElementConstraint ec(hex, g);
  ElementConstraint::Point like, out;
  Probe pr;
  EXPECT_FALSE(ec.place({5, 5, 5}, like, 20, 0, out, pr));
  EXPECT_TRUE(pr.why == ProjectFailure::left_domain || pr.why == ProjectFailure::no_convergence);
  // A world point near the surface inverts and projects.
  Probe ok;
  const Vec3 x = hex.world(0, {0.5, 0.5, 0.86}, nullptr);
  ASSERT_TRUE(ec.place(x, like, 20, 0, out, ok));
  EXPECT_NEAR(norm(out.s.u - Vec3{0.5, 0.5, 0.5}), 0.35, 1e-8);
}

// --- volume interior -----------------------------------------------------------------

TEST(EngineVolume, PacksTheInsideOfABallWithTwelveIdealNeighbours) {
  // SPEC §7 volume packing: the boundary particles are fixed (here a
  // Fibonacci sphere at the hexagonal density of spacing s) and repel the
  // free interior ones, which the volume constraint keeps inside F < 0.
  const double R = 1.0, s = 0.3;
  const Ball f({0, 0, 0}, R, 1.2);
  const VolumeConstraint vc(f, 0.0);
  VolumeConstraint::Point probe;
  EXPECT_EQ(vc.ideal_neighbours(probe), 12);
  ParticleEngine<VolumeConstraint> e(vc, quiet_params(s));
  const int nb_fixed = int(std::lround(4 * kPi * R * R * 2 / (std::sqrt(3.0) * s * s)));
  for (int k = 0; k < nb_fixed; ++k) {
    const double z = 1 - 2 * (k + 0.5) / nb_fixed, q = std::sqrt(1 - z * z), ph = 2.399963229728653 * k;
    VolumeConstraint::Point b;
    b.x = Vec3{q * std::cos(ph), q * std::sin(ph), z} * R;
    b.n = b.x / R;
    e.add(b, 0, true);
  }
  std::vector<Vec3> xs;
  for (int k = 0; k < 60; ++k)  // inside and outside: outside ones are pulled in
    xs.push_back(Vec3{counter_uniform(3, k, 0, 1), counter_uniform(3, k, 0, 2), counter_uniform(3, k, 0, 3)} * 2.2 -
                 Vec3{1.1, 1.1, 1.1});
  seed_points(e, xs, VolumeConstraint::Point{});
  ASSERT_GT(e.particles().size(), std::size_t(nb_fixed) + 40);
  const auto lr = e.relax("volume", false);
  EXPECT_GT(lr.splits, 0u);
  std::vector<Vec3> all, free;
  for (const auto& q : e.particles()) {
    all.push_back(q.p.x);
    if (q.fixed) continue;
    EXPECT_LT(norm(q.p.x), R);  // never outside
    free.push_back(q.p.x);
  }
  e.measure();
  std::size_t deep = 0;
  double nb = 0;
  for (const auto& q : e.particles())
    if (!q.fixed && norm(q.p.x) < R - 2 * s) {
      ++deep;
      nb += q.neighbours;
    }
  // A close packing at nearest distance d has √2/d³ points per volume.
  const std::vector<double> d = nearest(all);
  double nn = 0;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (norm(all[i]) < R - 2 * s) nn += d[i];
  nn /= double(deep);
  EXPECT_GT(nn, 0.7 * s);
  EXPECT_LT(nn, 1.3 * s);
  // The deep ball r < R − 2s holds its share of a close packing at d = nn
  // within a factor 2 (no depletion of the middle by a crowded wall).
  const double rd = R - 2 * s, est = 4.0 / 3 * kPi * rd * rd * rd * std::sqrt(2.0) / (nn * nn * nn);
  EXPECT_GT(double(deep), 0.5 * est);
  EXPECT_LT(double(deep), 2.0 * est);
  // Neighbours are counted within the support s/β = √3 s: a close packing
  // at d ∈ [0.7 s, 1.3 s] has its 12 + 6 first shells there, and its third
  // shell (24 at √3 d) too when d < s.
  EXPECT_GE(nb / double(deep), 12.0);
  EXPECT_LE(nb / double(deep), 42.0);
  // The free particles fill the ball minus the fixed layer's half spacing.
  const double rf = R - nn / 2, ball = 4.0 / 3 * kPi * rf * rf * rf * std::sqrt(2.0) / (nn * nn * nn);
  EXPECT_GT(double(free.size()), 0.5 * ball);
  EXPECT_LT(double(free.size()), 2.0 * ball);
  std::fprintf(stderr, "volume packing: %zu free, %zu deep (estimate %.1f), nn %.3f, neighbours %.2f\n", free.size(),
               deep, est, nn, nb / double(deep));
}

// --- particle types ----------------------------------------------------------------------

TEST(EngineTypes, QuadTypesScaleLikePairsBySqrtTwo) {
  const Ball f({0, 0, 0}, 1.0, 1.5);
  const SurfaceConstraint sc(f, 0.0, false);
  EngineParams p = quiet_params(0.2);
  set_quad_types(p);
  ParticleEngine<SurfaceConstraint> e(sc, p);
  SurfaceConstraint::Point a, b;
  Probe pr;
  ASSERT_TRUE(sc.place({1.1, 0, 0}, a, 20, 0, a, pr));
  ASSERT_TRUE(sc.place({0, 1.1, 0}, b, 20, 0, b, pr));
  e.add(a, 0);
  e.add(b, 0);
  e.add(b, 1);
  const auto& q = e.particles();
  EXPECT_NEAR(e.pair_alpha(q[0], q[2]) / e.pair_alpha(q[0], q[1]), std::sqrt(2.0), 1e-15);
  EXPECT_NEAR(e.pair_alpha(q[0], q[2]), engine_beta() / 0.2, 1e-12);
}

// Two types on a sphere, no population control: like pairs keep √2 farther
// apart than unlike ones, so each particle's nearest like neighbour lies
// clearly farther than its nearest unlike one (untyped: about equal).
TEST(EngineTypes, LikeNeighboursSitFartherApart) {
  const Ball f({0, 0, 0}, 1.0, 1.5);
  const SurfaceConstraint sc(f, 0.0, false);
  auto run = [&](bool typed) {
    EngineParams p = quiet_params(0.25);
    p.population_control = false;
    if (typed) set_quad_types(p);
    ParticleEngine<SurfaceConstraint> e(sc, p);
    const int n = 200;
    for (int k = 0; k < n; ++k) {
      const double z = 1 - 2 * (k + 0.5) / n, q = std::sqrt(1 - z * z), ph = 2.39996 * k;
      SurfaceConstraint::Point pt;
      Probe pr;
      EXPECT_TRUE(sc.place(Vec3{q * std::cos(ph), q * std::sin(ph), z} * 1.01, pt, 20, 0, pt, pr));
      e.add(pt, std::uint8_t(counter_uniform(9, std::uint64_t(k), 0, 1) < 0.5 ? 0 : 1));
    }
    e.relax("types", false);
    double like = 0, unlike = 0;
    const auto& ps = e.particles();
    for (std::size_t i = 0; i < ps.size(); ++i) {
      double dl = 1e300, du = 1e300;
      for (std::size_t j = 0; j < ps.size(); ++j) {
        if (i == j) continue;
        const double d = norm(ps[i].p.x - ps[j].p.x);
        (ps[i].type == ps[j].type ? dl : du) = std::min(ps[i].type == ps[j].type ? dl : du, d);
      }
      like += dl;
      unlike += du;
    }
    return like / unlike;
  };
  // A checkerboard gives √2; 200 particles on a closed sphere cannot form
  // one (grow_types grows one grain, which meets itself along seams), so the
  // ratio lands near 1.19 (1.188 with today's arithmetic; 1.2 with libm's
  // cotangent), the untyped packing near 1.0.
  const double plain = run(false), typed = run(true);
  EXPECT_LT(plain, 1.1);
  EXPECT_GT(typed, 1.15);
  EXPECT_GT(typed, plain + 0.15);
}

// A perfect square lattice (on a sphere so large that the patch is flat to
// 1e-3 spacings) with random types: grow_types must colour it as one
// checkerboard, every nearest pair (a apart) unlike and every diagonal pair
// (√2 a apart) like, since each pair prefers unlike with a weight that falls
// with the distance and the growth types each particle against the larger
// pull of its typed neighbours.
TEST(EngineTypes, GrowTypesColoursASquareLatticeAsOneCheckerboard) {
  const double R = 50, a = 0.2;
  const Ball f({0, 0, 0}, R, 1.5 * R);
  const SurfaceConstraint sc(f, 0.0, false);
  EngineParams p = quiet_params(a);
  set_quad_types(p);
  ParticleEngine<SurfaceConstraint> e(sc, p);
  const int m = 8;
  for (int i = -m; i <= m; ++i)
    for (int j = -m; j <= m; ++j) {
      SurfaceConstraint::Point pt;
      Probe pr;
      ASSERT_TRUE(sc.place({i * a, j * a, R}, pt, 20, 0, pt, pr));
      e.add(pt, std::uint8_t(counter_uniform(5, std::uint64_t((i + m) * 100 + j + m), 0, 1) < 0.5 ? 0 : 1));
    }
  e.grow_types(true);
  const auto& ps = e.particles();
  std::size_t nearest_pairs = 0, diagonal_pairs = 0;
  for (std::size_t i = 0; i < ps.size(); ++i)
    for (std::size_t j = i + 1; j < ps.size(); ++j) {
      const double d = norm(ps[i].p.x - ps[j].p.x) / a;
      if (std::fabs(d - 1) < 0.01) {
        ++nearest_pairs;
        EXPECT_NE(ps[i].type, ps[j].type) << i << " " << j;
      } else if (std::fabs(d - std::sqrt(2.0)) < 0.01) {
        ++diagonal_pairs;
        EXPECT_EQ(ps[i].type, ps[j].type) << i << " " << j;
      }
    }
  const std::size_t side = 2 * m + 1;
  EXPECT_EQ(nearest_pairs, 2 * side * (side - 1));
  EXPECT_EQ(diagonal_pairs, 2 * (side - 1) * (side - 1));
  // Coloured again, the checkerboard is kept (no like pair left to save).
  EXPECT_EQ(e.grow_types(false), 0u);
}

}  // namespace
}  // namespace pm
