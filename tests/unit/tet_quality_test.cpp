// Tetrahedral mesh quality (meshstats on .mesh): dihedral angles and radius
// ratios with closed forms, and the mesh checks on a cube cut into 6 tetrahedra.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <tbb/global_control.h>

#include "pm/base/error.h"
#include "pm/io/medit.h"
#include "pm/mesh/tet_quality.h"
#include "test_util.h"

namespace pm {
namespace {

TEST(TetQuality, RegularTetrahedron) {
  // Corners of a cube alternately: all six dihedral angles are acos(1/3).
  const Vec3 a{1, 1, 1}, b{1, -1, -1}, c{-1, 1, -1}, d{-1, -1, 1};
  for (double x : tet_dihedrals(a, b, c, d)) EXPECT_NEAR(x, std::acos(1.0 / 3) * 180 / M_PI, 1e-12);
  EXPECT_NEAR(tet_radius_ratio(a, b, c, d), 1.0, 1e-12);
}

TEST(TetQuality, CornerTetrahedron) {
  // o, e1, e2, e3: right angles at the three axis edges, acos(1/√3) at the
  // others; r_in = 1/(3 + √3), r_circ = √3/2.
  const auto dih = tet_dihedrals({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1});
  for (int e = 0; e < 3; ++e) EXPECT_NEAR(dih[std::size_t(e)], 90.0, 1e-12);
  for (int e = 3; e < 6; ++e) EXPECT_NEAR(dih[std::size_t(e)], std::acos(1 / std::sqrt(3.0)) * 180 / M_PI, 1e-12);
  EXPECT_NEAR(tet_radius_ratio({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}),
              3 / (3 + std::sqrt(3.0)) / (std::sqrt(3.0) / 2), 1e-12);
  EXPECT_EQ(tet_radius_ratio({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}), 0.0);  // flat
}

// The unit cube as 6 tetrahedra around the diagonal 0-7 (Kuhn), material 1
// for x > y, else 2, and its 12 boundary triangles.
LabelledTets kuhn_cube() {
  LabelledTets t;
  for (int k = 0; k < 8; ++k) t.vertices.push_back({double(k & 1), double((k >> 1) & 1), double(k >> 2)});
  t.tets = {{0, 1, 3, 7}, {0, 1, 7, 5}, {0, 2, 7, 3}, {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 7, 6}};
  for (auto& c : t.tets) {
    const Vec3 &a = t.vertices[std::size_t(c[0])], &b = t.vertices[std::size_t(c[1])],
               &d = t.vertices[std::size_t(c[2])], &e = t.vertices[std::size_t(c[3])];
    if (dot(b - a, cross(d - a, e - a)) < 0) std::swap(c[2], c[3]);
    const Vec3 centre = (a + b + d + e) / 4.0;
    t.materials.push_back(centre.x > centre.y ? 1 : 2);
  }
  // Each cube face is split by its diagonal through corner 0 or 7.
  t.triangles = {{0, 3, 1}, {0, 2, 3}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                 {2, 7, 3}, {2, 6, 7}, {0, 6, 2}, {0, 4, 6}, {1, 3, 7}, {1, 7, 5}};
  t.triangle_labels.assign(t.triangles.size(), {0, 1});
  return t;
}

TEST(TetQuality, KuhnCubeIsClosedPositiveAndComplete) {
  LabelledTets t = kuhn_cube();
  // The interface x = y (the plane through 0, 3, 4, 7) is the two faces
  // (0, 3, 7) and (0, 4, 7) between materials 1 and 2: listed too.
  t.triangles.push_back({0, 3, 7});
  t.triangles.push_back({0, 7, 4});
  t.triangle_labels.push_back({1, 2});
  t.triangle_labels.push_back({1, 2});
  const TetQuality q = tet_quality(t);
  EXPECT_EQ(q.overall.tets, 6u);
  EXPECT_NEAR(q.overall.volume, 1.0, 1e-14);
  EXPECT_NEAR(q.materials.at(1).volume, 0.5, 1e-14);
  EXPECT_NEAR(q.materials.at(2).volume, 0.5, 1e-14);
  EXPECT_EQ(q.overall.non_positive, 0u);
  EXPECT_EQ(q.boundary_faces, 12u);
  EXPECT_EQ(q.interface_faces, 2u);
  EXPECT_EQ(q.boundary_nonmanifold_edges, 0u);
  EXPECT_EQ(q.triangles_missing, 0u);
  EXPECT_EQ(q.triangles_extra, 0u);
  // Kuhn tetrahedra: dihedral angles 45°, 60° and 90° only; ρ the same for all.
  EXPECT_NEAR(q.overall.dihedral_min, 45.0, 1e-9);
  EXPECT_NEAR(q.overall.dihedral_max, 90.0, 1e-9);
  EXPECT_EQ(q.overall.under_10, 0u);
  EXPECT_NEAR(q.overall.rr_min, q.overall.rr_mean, 1e-12);
  EXPECT_TRUE(check_tet_requirements(q, "positive,boundary_manifold,triangles_match,min_dihedral>=45,"
                                        "share_under_10<=0")
                  .empty());
  EXPECT_EQ(check_tet_requirements(q, "min_dihedral>=50").size(), 1u);
  EXPECT_THROW(check_tet_requirements(q, "watertight"), UsageError);
}

TEST(TetQuality, FindsAnInvertedTetMissingTrianglesAndANonManifoldBoundary) {
  LabelledTets t = kuhn_cube();  // without the interface triangles: 2 missing
  std::swap(t.tets[0][0], t.tets[0][1]);
  const TetQuality q = tet_quality(t);
  EXPECT_EQ(q.overall.non_positive, 1u);
  EXPECT_EQ(q.triangles_missing, 2u);
  EXPECT_EQ(check_tet_requirements(q, "positive,triangles_match").size(), 2u);
  t = kuhn_cube();
  t.tets.pop_back();  // a notch: two listed triangles are no boundary face now
  t.materials.pop_back();
  const TetQuality h = tet_quality(t);
  EXPECT_EQ(h.boundary_nonmanifold_edges, 0u);  // a boundary is always closed, here manifold too
  EXPECT_EQ(h.triangles_extra, 2u);
  EXPECT_EQ(h.triangles_missing, 3u);  // the notch's two inner faces, and the interface (0, 3, 7) left
  // Two tetrahedra sharing one edge only: that edge has 4 boundary faces.
  LabelledTets e;
  e.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}, {2, 1, 1}};
  e.tets = {{0, 1, 2, 3}, {0, 1, 5, 4}};
  for (auto& c : e.tets) {
    const Vec3 &a = e.vertices[std::size_t(c[0])], &b = e.vertices[std::size_t(c[1])],
               &d = e.vertices[std::size_t(c[2])], &f = e.vertices[std::size_t(c[3])];
    if (dot(b - a, cross(d - a, f - a)) < 0) std::swap(c[2], c[3]);
  }
  e.materials = {1, 1};
  const TetQuality n = tet_quality(e);
  EXPECT_EQ(n.boundary_faces, 8u);
  EXPECT_EQ(n.boundary_nonmanifold_edges, 1u);
  EXPECT_EQ(check_tet_requirements(n, "boundary_manifold").size(), 1u);
}

TEST(TetQuality, IssueTargetsShareAndKeyNames) {
  // Kuhn tetrahedra (45°, 60°, 90°) lie within 25..140°; a sliver (four
  // nearly coplanar corners: angles near 0° and 180°) does not.
  LabelledTets t = kuhn_cube();
  t.vertices.push_back({3, 0, 0});
  t.vertices.push_back({4, 0, 0});
  t.vertices.push_back({3.5, 1, 0.02});
  t.vertices.push_back({3.5, -1, 0.02});
  t.tets.push_back({8, 9, 10, 11});
  t.materials.push_back(5);
  {
    auto& c = t.tets.back();
    const Vec3 &a = t.vertices[8], &b = t.vertices[9], &d = t.vertices[10], &e = t.vertices[11];
    if (dot(b - a, cross(d - a, e - a)) < 0) std::swap(c[2], c[3]);
  }
  t.triangles.clear();
  t.triangle_labels.clear();
  const TetQuality q = tet_quality(t);
  EXPECT_EQ(q.overall.within_25_140, 6u);
  EXPECT_NEAR(q.overall.share_25_140(), 6.0 / 7, 1e-15);
  EXPECT_EQ(q.materials.at(5).within_25_140, 0u);
  EXPECT_GT(q.overall.dihedral_max, 170.0);
  EXPECT_LT(q.overall.dihedral_min, 5.0);
  // The issue's key names and the older ones, with the value found on failure.
  const auto failed = check_tet_requirements(q, "dihedral_min>=12, dihedral_max<=160,share_25_140>=0.99,rr_mean>=0");
  ASSERT_EQ(failed.size(), 3u);
  EXPECT_EQ(failed[0].rfind("dihedral_min>=12 (have ", 0), 0u) << failed[0];
  EXPECT_EQ(failed[2].rfind("share_25_140>=0.99 (have 0.857143)", 0), 0u) << failed[2];
  EXPECT_EQ(check_tet_requirements(q, "min_dihedral>=12,max_dihedral<=160").size(), 2u);
  EXPECT_TRUE(check_tet_requirements(q, "share_25_140>0.85,dihedral_max<180,rr_min>=0").empty());
  EXPECT_THROW(check_tet_requirements(q, "dihedral_min>=twelve"), UsageError);
  EXPECT_THROW(check_tet_requirements(q, "dihedral_mean>=12"), UsageError);
  EXPECT_EQ(to_json(q)["overall"]["share_25_140"].get<double>(), q.overall.share_25_140());
}

TEST(TetQuality, MeditRoundTrip) {
  const LabelledTets t = kuhn_cube();
  const std::string path = test::temp_dir() + "/kuhn.mesh";
  write_medit_tets(t, path);
  ASSERT_TRUE(medit_has_tetrahedra(path));
  const LabelledTets r = read_medit_tets(path);
  ASSERT_EQ(r.tets.size(), 6u);
  EXPECT_EQ(r.materials, t.materials);
  EXPECT_EQ(r.triangles.size(), 12u);
  EXPECT_NEAR(tet_quality(r).overall.volume, 1.0, 1e-12);
}

// n^3 Kuhn cubes (6 n^3 tetrahedra) with the inner vertices jittered (the
// box stays the box, unless box_too), materials by the cube's parity; no
// triangles.
LabelledTets jittered_grid(int n, double jitter, bool box_too = false) {
  LabelledTets t;
  std::uint64_t state = 11;
  auto u = [&] {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(state >> 11) / double(1ULL << 53) - 0.5;
  };
  auto id = [&](int i, int j, int k) { return (k * (n + 1) + j) * (n + 1) + i; };
  for (int k = 0; k <= n; ++k)
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) {
        const bool inner = i > 0 && j > 0 && k > 0 && i < n && j < n && k < n;
        const double s = inner || box_too ? jitter : 0.0;
        t.vertices.push_back(Vec3(i + s * u(), j + s * u(), k + s * u()));
      }
  const LabelledTets cube = kuhn_cube();
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        for (const auto& c : cube.tets) {
          std::array<int, 4> q;
          for (int v = 0; v < 4; ++v) q[std::size_t(v)] = id(i + (c[std::size_t(v)] & 1), j + ((c[std::size_t(v)] >> 1) & 1), k + (c[std::size_t(v)] >> 2));
          t.tets.push_back(q);
          t.materials.push_back(1 + (i + j + k) % 2);
        }
  return t;
}

TEST(TetQuality, RangeAndBinsFromCosinesEqualTheSixAngles) {
  // tet_quality bins angles by their normal cosines and takes two arc
  // cosines per tetrahedron: the same numbers as the six angles give (every
  // vertex jittered, so that no angle sits on a bin's edge, 60° or 90°).
  const LabelledTets t = jittered_grid(8, 0.9, true);
  TetStats ref;
  for (const auto& c : t.tets) {
    const Vec3 &a = t.vertices[std::size_t(c[0])], &b = t.vertices[std::size_t(c[1])],
               &d = t.vertices[std::size_t(c[2])], &e = t.vertices[std::size_t(c[3])];
    const std::array<double, 6> six = tet_dihedrals(a, b, d, e);
    const auto [lo, hi] = std::minmax_element(six.begin(), six.end());
    const DihedralRange r = tet_dihedral_range(a, b, d, e);
    ASSERT_EQ(r.min, *lo);
    ASSERT_EQ(r.max, *hi);
    ref.dihedral_min = std::min(ref.dihedral_min, *lo);
    ref.dihedral_max = std::max(ref.dihedral_max, *hi);
    for (double x : six) ++ref.dihedral_hist[std::size_t(std::clamp(int(x / 10), 0, 17))];
    ref.under_10 += *lo < 10;
    ref.within_25_140 += *lo >= 25 && *hi <= 140;
  }
  const TetQuality q = tet_quality(t);
  EXPECT_EQ(q.overall.dihedral_min, ref.dihedral_min);
  EXPECT_EQ(q.overall.dihedral_max, ref.dihedral_max);
  EXPECT_EQ(q.overall.dihedral_hist, ref.dihedral_hist);
  EXPECT_EQ(q.overall.under_10, ref.under_10);
  EXPECT_EQ(q.overall.within_25_140, ref.within_25_140);
  EXPECT_GT(ref.under_10, 0u);  // the jitter makes slivers: the counts are tested
  EXPECT_LT(ref.within_25_140, t.tets.size());
}

TEST(TetQuality, SameNumbersForAnyThreadCount) {
  // 48k tetrahedra: several blocks of the parallel reduction.
  const LabelledTets t = jittered_grid(20, 0.2);
  TetQuality one, four;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    one = tet_quality(t);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 4);
    four = tet_quality(t);
  }
  EXPECT_EQ(one.overall.rr_mean, four.overall.rr_mean);  // bit for bit
  EXPECT_EQ(one.overall.volume, four.overall.volume);
  EXPECT_EQ(one.materials.at(2).rr_mean, four.materials.at(2).rr_mean);
  EXPECT_EQ(one.overall.rr_hist, four.overall.rr_hist);
  EXPECT_EQ(one.overall.tets, 48000u);
  EXPECT_EQ(one.overall.non_positive, 0u);
  EXPECT_NEAR(one.overall.volume, 8000.0, 1e-9);  // the box
  // The closed grid: every boundary face once, a manifold, no overfull faces;
  // the parity materials make every inner cube face an interface.
  EXPECT_EQ(one.boundary_faces, 6u * 2 * 20 * 20);
  EXPECT_EQ(one.boundary_nonmanifold_edges, 0u);
  EXPECT_EQ(one.overfull_faces, 0u);
  EXPECT_EQ(one.interface_faces, 3u * 2 * 19 * 20 * 20);
}

}  // namespace
}  // namespace pm
