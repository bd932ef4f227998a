#include "pm/sample/multiparticles.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

#include "analytic_materials.h"
#include "pm/base/error.h"
#include "pm/base/volume.h"
#include "pm/sample/junction_constraint.h"

namespace pm {
namespace {

double f_of(const MaterialSet& m, int label, const Vec3& x) {
  for (std::size_t i = 0; i < m.size(); ++i)
    if (m.labels[i] == label) return -m.fields[i]->value(x);
  return std::numeric_limits<double>::quiet_NaN();
}

MultiParticleParams quiet(double s) {
  MultiParticleParams p;
  p.spacing = s;
  p.progress = false;
  return p;
}

// The run without and with the junction repair.
std::pair<MultiParticleResult, MultiParticleResult> without_and_with_repair(const MaterialSet& m,
                                                                            const std::vector<JunctionSeed>& seeds,
                                                                            MultiParticleParams p) {
  p.repair_junctions = false;
  MultiParticleResult plain = distribute_multi_particles(m, seeds, nullptr, p);
  p.repair_junctions = true;
  return {std::move(plain), distribute_multi_particles(m, seeds, nullptr, p)};
}

// Closest approach of two particles of `junction` materials on different cells.
double closest_of_different_cells(const MultiParticleResult& q, int junction) {
  double best = 1e300;
  for (std::size_t a = 0; a < q.positions.size(); ++a)
    for (std::size_t b = a + 1; b < q.positions.size(); ++b)
      if (q.junction[a] == junction && q.junction[b] == junction && q.labels[a] != q.labels[b])
        best = std::min(best, norm(q.positions[a] - q.positions[b]));
  return best;
}

// Checks every particle against the fields: on its junction (|f_a - f_b| <=
// tol for its labels), no other material above, normals from a into b.
void expect_on_junctions(const MaterialSet& m, const MultiParticleResult& r, double tol) {
  ASSERT_EQ(r.positions.size(), r.labels.size());
  for (std::size_t i = 0; i < r.positions.size(); ++i) {
    const Vec3& x = r.positions[i];
    const int n = r.junction[i];
    ASSERT_GE(n, 2);
    ASSERT_LE(n, 4);
    double top = -1e300, low = 1e300;
    for (int k = 0; k < n; ++k) {
      const double f = f_of(m, r.labels[i][std::size_t(k)], x);
      top = std::max(top, f);
      low = std::min(low, f);
    }
    EXPECT_LE(top - low, tol) << "particle " << i << " junction " << n;
    for (std::size_t o = 0; o < m.size(); ++o) {
      bool in = false;
      for (int k = 0; k < n; ++k) in = in || r.labels[i][std::size_t(k)] == m.labels[o];
      if (!in) {
        EXPECT_LE(-m.fields[o]->value(x), top + tol) << "particle " << i << " is under material " << m.labels[o];
      }
    }
    if (n == 2) {
      EXPECT_NEAR(norm(r.normals[i]), 1.0, 1e-9);
      // Moving along the normal enters label_b: f_b - f_a grows.
      const double e = 1e-4;
      const Vec3 y = x + r.normals[i] * e;
      EXPECT_GT(f_of(m, r.labels[i][1], y) - f_of(m, r.labels[i][0], y), 0.0) << i;
    } else {
      EXPECT_EQ(norm(r.normals[i]), 0.0);
    }
    for (int k = n; k < 4; ++k) EXPECT_EQ(r.labels[i][std::size_t(k)], -1);
  }
}

TEST(MultiParticles, ThreeWedgesCurveAndSurfaces) {
  const MaterialSet m = test::three_wedges(0.3);
  const std::vector<JunctionSeed> seeds = junction_seeds_from_materials(m);
  const double s = 0.2;
  const MultiParticleResult r = distribute_multi_particles(m, seeds, nullptr, quiet(s));
  expect_on_junctions(m, r, 1e-6);
  EXPECT_EQ(r.levels[0].particles, 0u);
  EXPECT_EQ(r.levels[1].cells, 1u);
  EXPECT_EQ(r.levels[2].cells, 3u);
  EXPECT_TRUE(r.levels[1].converged);
  EXPECT_TRUE(r.levels[2].converged);
  // The triple line is the z axis from -1 to 1: particles on it within 1e-6,
  // spaced s apart (mean gap within 15%, every gap within 40%).
  std::vector<double> z;
  for (std::size_t i = 0; i < r.positions.size(); ++i)
    if (r.junction[i] == 3) {
      EXPECT_LT(std::hypot(r.positions[i].x, r.positions[i].y), 1e-6);
      z.push_back(r.positions[i].z);
    }
  ASSERT_GE(z.size(), 8u);
  std::sort(z.begin(), z.end());
  const double mean_gap = (z.back() - z.front()) / double(z.size() - 1);
  EXPECT_NEAR(mean_gap, s, 0.15 * s);
  for (std::size_t k = 1; k < z.size(); ++k) EXPECT_NEAR(z[k] - z[k - 1], s, 0.4 * s);
  // Hexagonal estimate for the surfaces (within the stable band 0.8-1.3).
  const std::size_t ns = r.levels[2].particles;
  EXPECT_GT(ns, 3 * 30u);
  EXPECT_LT(ns, 3 * 110u);
  // Surface particles keep at least ~half a spacing from the curve particles.
  for (std::size_t i = 0; i < r.positions.size(); ++i) {
    if (r.junction[i] == 2) {
      EXPECT_GT(std::hypot(r.positions[i].x, r.positions[i].y), 0.3 * s);
    }
  }
}

// Without curve seeds the triple line (the z axis) is left to the surfaces:
// particles of two interfaces crowd against it from both sides. The repair
// turns each pair closer than h/4 into one particle on the line.
// The engine reads a junction particle's pair rules from its cached cell
// (kKeyedPairs): for every pair of cells of four materials, fixed or not,
// the keyed rules give what the particle-reading ones give.
TEST(MultiParticles, KeyedPairRulesAgreeWithTheParticleRules) {
  const MaterialSet m = test::four_tetrahedral();
  JunctionConstraint c(m, test::cube(1.0), 1e-3);
  std::vector<std::int32_t> ids;
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) {
      ids.push_back(c.cell_index(make_cell({a, b})));
      for (int d = b + 1; d < 4; ++d) ids.push_back(c.cell_index(make_cell({a, b, d})));
    }
  ids.push_back(c.cell_index(make_cell({0, 1, 2, 3})));
  c.finish_cells();
  ASSERT_EQ(ids.size(), 11u);
  int seen = 0, weighted = 0;
  for (std::int32_t a : ids)
    for (std::int32_t b : ids) {
      const JunctionConstraint::Point i = c.of_cell(a), o = c.of_cell(b);
      for (bool fixed : {false, true}) {
        const bool s = c.sees(i, o, fixed);
        EXPECT_EQ(c.sees_key(i, c.pair_key(o), fixed), s) << a << " " << b << " " << fixed;
        seen += s;
      }
      const bool w = c.weighted(i) && c.same_cell(i, o);
      EXPECT_EQ(c.weighted_key(i, c.pair_key(o)), w) << a << " " << b;
      weighted += w;
    }
  // Each cell sees its own particles (fixed or not) and the fixed ones of
  // the cells that bound it: a surface is bounded by 2 curves and the
  // point, a curve by the point.
  EXPECT_EQ(seen, 11 * 2 + 6 * 3 + 4 * 1);
  EXPECT_EQ(weighted, 6);  // surface particles of one cell only
}

TEST(MultiParticles, JunctionRepairPutsMissedCurvesOnTheLine) {
  const MaterialSet m = test::three_wedges(0.0);
  std::vector<JunctionSeed> seeds;
  for (const JunctionSeed& j : junction_seeds_from_materials(m))
    if (j.count == 2) seeds.push_back(j);
  const double s = 0.2;
  const auto [plain, r] = without_and_with_repair(m, seeds, quiet(s));
  EXPECT_EQ(plain.junction_repairs, 0u);
  for (int j : plain.junction) EXPECT_EQ(j, 2);
  // Surface particles of different interfaces.
  ASSERT_LT(closest_of_different_cells(plain, 2), 0.25 * s);  // the situation the repair is for
  EXPECT_GT(r.junction_repairs, 0u);
  EXPECT_GE(closest_of_different_cells(r, 2), 0.25 * s);      // every such pair was merged
  expect_on_junctions(m, r, 1e-6);
  std::size_t on_line = 0;
  for (std::size_t i = 0; i < r.positions.size(); ++i)
    if (r.junction[i] == 3) {
      ++on_line;
      EXPECT_LT(std::hypot(r.positions[i].x, r.positions[i].y), 1e-6);
    }
  EXPECT_EQ(on_line, r.junction_repairs);
  EXPECT_EQ(r.positions.size() + r.junction_repairs, plain.positions.size());
}

// Four materials meeting at a quadruple point (the origin) that has no seed:
// the six triple curves are sampled up to it, and particles of two curves
// that share two materials crowd there. The repair replaces such a pair by
// one particle on the quadruple point (frog15 after tightening: two curve
// particles 0.002 mm apart, four triangles of radius ratio 0.002).
TEST(MultiParticles, RepairPutsAMissedQuadruplePointWhereCurvesMeet) {
  const MaterialSet m = test::four_tetrahedral();
  std::vector<JunctionSeed> seeds;
  for (const JunctionSeed& j : junction_seeds_from_materials(m))
    if (j.count < 4) seeds.push_back(j);
  const double s = 0.2;
  const auto [plain, r] = without_and_with_repair(m, seeds, quiet(s));
  for (int j : plain.junction) EXPECT_LT(j, 4);
  // Particles of different triple curves.
  ASSERT_LT(closest_of_different_cells(plain, 3), 0.25 * s);  // the situation the repair is for
  EXPECT_EQ(plain.corner_repairs + plain.curve_pairs_dropped, 0u);
  EXPECT_EQ(r.corner_repairs, 1u);
  EXPECT_GE(closest_of_different_cells(r, 3), 0.25 * s);
  std::size_t corners = 0;
  for (std::size_t i = 0; i < r.positions.size(); ++i)
    if (r.junction[i] == 4) {
      ++corners;
      EXPECT_LT(norm(r.positions[i]), 1e-5);  // on the quadruple point
    }
  EXPECT_EQ(corners, 1u);
  expect_on_junctions(m, r, 1e-6);
}

// A thin fin of material 1 (a 16 degree wedge along z) in background 0: the
// interface folds at the fin's edge, where particles on its two faces have
// normals 164 degrees apart and the normal weighting hides them from each
// other. Two of them closer than h/4 make a sliver of a triangle; the repair
// merges such a pair into one particle at its middle, on the interface.
TEST(MultiParticles, RepairMergesOneInterfacesPairsAcrossAFold) {
  MaterialSet m;
  test::add_background(m, 0);
  const double t = 8.0 * M_PI / 180.0;
  const Vec3 na{std::sin(t), -std::cos(t), 0}, nb{std::sin(t), std::cos(t), 0};
  test::add_material(
      m, 1,
      [na, nb](const Vec3& x, Vec3& g) {
        const double a = dot(na, x), b = dot(nb, x);
        g = a < b ? na : nb;
        return std::min(a, b);
      },
      test::cube(1.0));
  const std::vector<JunctionSeed> seeds = junction_seeds_from_materials(m);
  const double s = 0.1;
  const auto [plain, r] = without_and_with_repair(m, seeds, quiet(s));
  auto closest_pair = [](const MultiParticleResult& q) {
    double best = 1e300;
    for (std::size_t a = 0; a < q.positions.size(); ++a)
      for (std::size_t b = a + 1; b < q.positions.size(); ++b)
        best = std::min(best, norm(q.positions[a] - q.positions[b]));
    return best;
  };
  EXPECT_EQ(plain.close_pairs_merged, 0u);
  ASSERT_LT(closest_pair(plain), 0.25 * s);  // the situation the repair is for
  EXPECT_GT(r.close_pairs_merged, 0u);
  EXPECT_EQ(r.junction_repairs, 0u);  // two materials: no triple junction
  EXPECT_GE(closest_pair(r), 0.25 * s);
  EXPECT_EQ(r.positions.size() + r.close_pairs_merged, plain.positions.size());
  // Every particle, the merged ones among them, on the interface f_1 = f_0.
  // (Not expect_on_junctions: its normal probe steps 1e-4, farther than the
  // fin is thick next to its edge.)
  for (std::size_t i = 0; i < r.positions.size(); ++i) {
    EXPECT_EQ(r.junction[i], 2);
    EXPECT_LE(std::fabs(f_of(m, 1, r.positions[i]) - f_of(m, 0, r.positions[i])), 1e-6) << i;
  }
}

TEST(MultiParticles, QuadruplePointIsOneParticleAndCurvesEndThere) {
  const MaterialSet m = test::four_tetrahedral();
  const std::vector<JunctionSeed> seeds = junction_seeds_from_materials(m, 0.1);
  MultiParticleParams p = quiet(0.25);
  p.surfaces = false;
  const MultiParticleResult r = distribute_multi_particles(m, seeds, nullptr, p);
  expect_on_junctions(m, r, 1e-6);
  ASSERT_EQ(r.levels[0].particles, 1u);
  EXPECT_LT(norm(r.positions[0]), 1e-6);
  EXPECT_EQ(r.levels[1].cells, 4u);
  // Each triple ray (-n_l) carries particles on it; the nearest to the
  // origin sits about one spacing away.
  for (int l = 0; l < 4; ++l) {
    const Vec3 dir = -test::tetra_direction(l);
    double nearest = 1e300;
    int count = 0;
    for (std::size_t i = 0; i < r.positions.size(); ++i) {
      if (r.junction[i] != 3) continue;
      const bool has_l = std::find(r.labels[i].begin(), r.labels[i].begin() + 3, l) != r.labels[i].begin() + 3;
      if (has_l) continue;
      ++count;
      const Vec3& x = r.positions[i];
      EXPECT_LT(norm(x - dir * dot(x, dir)), 1e-6);
      EXPECT_GT(dot(x, dir), 0.0);
      nearest = std::min(nearest, norm(x));
    }
    EXPECT_GE(count, 2) << l;
    EXPECT_NEAR(nearest, 0.25, 0.25 * 0.3) << l;
  }
}

TEST(MultiParticles, DeterministicForAnyThreadCount) {
  const MaterialSet m = test::two_spheres();
  const std::vector<JunctionSeed> seeds = junction_seeds_from_materials(m);
  MultiParticleResult a, b;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    a = distribute_multi_particles(m, seeds, nullptr, quiet(0.15));
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 4);
    b = distribute_multi_particles(m, seeds, nullptr, quiet(0.15));
  }
  ASSERT_EQ(a.positions.size(), b.positions.size());
  for (std::size_t i = 0; i < a.positions.size(); ++i) {
    EXPECT_EQ(a.positions[i], b.positions[i]) << i;
    EXPECT_EQ(a.labels[i], b.labels[i]) << i;
  }
  expect_on_junctions(m, a, 1e-6);
  // The triple circle (x = 0.075, radius sqrt(0.25 - 0.375²)) is sampled.
  const double rc = std::sqrt(0.25 - 0.375 * 0.375);
  int on_circle = 0;
  for (std::size_t i = 0; i < a.positions.size(); ++i)
    if (a.junction[i] == 3) {
      ++on_circle;
      EXPECT_NEAR(a.positions[i].x, 0.075, 1e-5);
      EXPECT_NEAR(std::hypot(a.positions[i].y, a.positions[i].z), rc, 1e-5);
    }
  // Circumference 2π rc ≈ 2.07 at s = 0.15: about 14 particles.
  EXPECT_NEAR(double(on_circle), 2 * M_PI * rc / 0.15, 3.0);
  EXPECT_EQ(a.levels[2].cells, 3u);  // 0|1, 0|2 and 1|2
}

// Background 0 and two pairs of overlapping spheres: 1 and 2 meet the
// background on a short triple circle (radius 0.12), 3 and 4 on a long one
// (radius 0.35). The short circle's crowded seed particles all have high
// energies; they must not all die in one population round while the long
// circle keeps the level populated.
MaterialSet short_and_long_circles() {
  MaterialSet m;
  test::add_background(m, 0);
  test::add_material(m, 1, test::ball({-0.55, 0, 0}, 0.2), test::cube(1.0));
  test::add_material(m, 2, test::ball({-0.3, 0, 0}, 0.15), test::cube(1.0));
  test::add_material(m, 3, test::ball({0.35, 0, 0}, 0.4), test::cube(1.0));
  test::add_material(m, 4, test::ball({0.6, 0, 0}, 0.35), test::cube(1.0));
  return m;
}

TEST(MultiParticles, ShortCurveKeepsParticles) {
  const MaterialSet m = short_and_long_circles();
  const std::vector<JunctionSeed> seeds = junction_seeds_from_materials(m);
  const double r_short = 0.12;  // sqrt(0.2² - 0.16²): circumference 0.75
  for (double s : {0.3, 0.4, 0.5, 0.6}) {
    MultiParticleParams p = quiet(s);
    p.surfaces = false;
    p.seed_thinning = 0;
    const MultiParticleResult r = distribute_multi_particles(m, seeds, nullptr, p);
    int on_short = 0, on_long = 0;
    for (std::size_t i = 0; i < r.positions.size(); ++i)
      if (r.junction[i] == 3) (r.positions[i].x < -0.02 ? on_short : on_long)++;
    EXPECT_GE(on_short, 1) << "spacing " << s << ": the short triple circle lost every particle";
    EXPECT_GE(on_long, 3) << "spacing " << s;
    EXPECT_EQ(r.levels[1].cells, 2u) << "spacing " << s;
    // Not crowded either: at most one particle per half spacing of arc (+1).
    EXPECT_LE(double(on_short), 2 * M_PI * r_short / (0.5 * s) + 1) << "spacing " << s;
  }
}

// A 24³ label map of three wedges (voxel size 1): materials from the masks'
// signed distances; particles must lie on the reconstructed junctions.
TEST(MultiParticles, LabelMapWedges) {
  Volume v(VoxelType::u8, Dims{24, 24, 24}, Geometry::with_spacing(1, 1, 1));
  const Vec3 c{11.5, 11.5, 0};
  for (std::size_t k = 0; k < 24; ++k)
    for (std::size_t j = 0; j < 24; ++j)
      for (std::size_t i = 0; i < 24; ++i) {
        const double a = std::atan2(double(j) - c.y, double(i) - c.x) * 180 / M_PI;  // (-180, 180]
        const int l = (a >= -30 && a < 90) ? 1 : ((a >= 90 || a < -150) ? 2 : 3);
        v.set(i, j, k, l);
      }
  const MaterialSet m = materials_from_labels(v);
  ASSERT_EQ(m.size(), 3u);
  const std::vector<JunctionSeed> seeds = junction_seeds_from_materials(m);
  const MultiParticleResult r = distribute_multi_particles(m, seeds, nullptr, quiet(3.0));
  expect_on_junctions(m, r, 1e-5);
  EXPECT_GE(r.levels[1].particles, 5u);
  EXPECT_EQ(r.levels[2].cells, 3u);
  for (std::size_t i = 0; i < r.positions.size(); ++i) {
    if (r.junction[i] == 3) {
      EXPECT_LT(std::hypot(r.positions[i].x - c.x, r.positions[i].y - c.y), 1.0);
    }
  }
}

// A sizing field instead of --spacing: h = 0.25 over the box gives chains
// spaced h along the triple line.
TEST(MultiParticles, SizingFieldSetsTheSpacing) {
  const MaterialSet m = test::three_wedges(0.0);
  const SizingField h = SizingField::constant(0.25, test::cube(1.0));
  MultiParticleParams p = quiet(0);
  p.surfaces = false;
  const MultiParticleResult r = distribute_multi_particles(m, junction_seeds_from_materials(m), &h, p);
  std::vector<double> z;
  for (std::size_t i = 0; i < r.positions.size(); ++i) {
    EXPECT_NEAR(r.spacing[i], 0.25, 1e-12);
    if (r.junction[i] == 3) z.push_back(r.positions[i].z);
  }
  ASSERT_GE(z.size(), 6u);
  std::sort(z.begin(), z.end());
  EXPECT_NEAR((z.back() - z.front()) / double(z.size() - 1), 0.25, 0.15 * 0.25);
}

TEST(MultiParticles, BadInput) {
  const MaterialSet m = test::three_wedges(0.0);
  const std::vector<JunctionSeed> seeds = junction_seeds_from_materials(m);
  MaterialSet one;
  one.labels = {m.labels[0]};
  one.fields = {m.fields[0]};
  EXPECT_THROW(distribute_multi_particles(one, seeds, nullptr, quiet(0.2)), InputError);
  EXPECT_THROW(distribute_multi_particles(m, seeds, nullptr, quiet(0)), UsageError);
  EXPECT_THROW(distribute_multi_particles(m, {}, nullptr, quiet(0.2)), InputError);
  std::vector<JunctionSeed> bad = seeds;
  bad[0].x.x = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(distribute_multi_particles(m, bad, nullptr, quiet(0.2)), InputError);
  // Domains that do not overlap.
  MaterialSet apart;
  test::add_material(apart, 1, [](const Vec3& x, Vec3& g) { g = {1, 0, 0}; return x.x; }, test::cube(1));
  Box far;
  far.lo = {5, 5, 5};
  far.hi = {6, 6, 6};
  test::add_material(apart, 2, [](const Vec3& x, Vec3& g) { g = {-1, 0, 0}; return -x.x; }, far);
  EXPECT_THROW(distribute_multi_particles(apart, seeds, nullptr, quiet(0.2)), InputError);
  // Labels that never touch: seeds name a pair the material set lacks.
  MaterialSet spheres = test::two_spheres();
  std::vector<JunctionSeed> only01;
  for (const JunctionSeed& s : junction_seeds_from_materials(spheres))
    if (s.count == 2 && s.labels[0] == 0 && s.labels[1] == 1) only01.push_back(s);
  spheres.labels.erase(spheres.labels.begin() + 1);
  spheres.fields.erase(spheres.fields.begin() + 1);  // materials 0 and 2 only
  try {
    distribute_multi_particles(spheres, only01, nullptr, quiet(0.2));
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no material interface"), std::string::npos) << e.what();
  }
}

TEST(MultiParticles, SeedsFromMesh) {
  Mesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}};
  mesh.vertex_scalars["junction"] = {2, 3};
  mesh.vertex_scalars["label_a"] = {4, 1};
  mesh.vertex_scalars["label_b"] = {2, 2};
  mesh.vertex_scalars["label_c"] = {-1, 3};
  mesh.vertex_scalars["label_d"] = {-1, -1};
  const std::vector<JunctionSeed> s = junction_seeds_from_mesh(mesh);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[0].count, 2);
  EXPECT_EQ(s[0].labels[0], 2);  // sorted
  EXPECT_EQ(s[0].labels[1], 4);
  EXPECT_EQ(s[1].labels[2], 3);
  mesh.vertex_scalars["junction"] = {5, 3};
  EXPECT_THROW(junction_seeds_from_mesh(mesh), InputError);
  mesh.vertex_scalars.erase("label_d");
  EXPECT_THROW(junction_seeds_from_mesh(mesh), InputError);
}

}  // namespace
}  // namespace pm
