#include "pm/mesh/tet_smooth.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/mesh/tet_quality.h"

namespace pm {

namespace {

double volume6(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return dot(b - a, cross(c - a, d - a));
}

// Circumcentre of a tetrahedron with 6 V = det != 0.
Vec3 circumcentre(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, double det) {
  const Vec3 u = b - a, v = c - a, w = d - a;
  return a + (cross(v, w) * norm2(u) + cross(w, u) * norm2(v) + cross(u, v) * norm2(w)) / (2.0 * det);
}

}  // namespace

TetSmoothResult odt_smooth(LabelledTets& t, std::size_t first_free, const TetSmoothParams& p) {
  if (p.sweeps < 1) throw UsageError("odt_smooth: sweeps must be >= 1, got " + std::to_string(p.sweeps));
  const std::size_t nv = t.vertices.size();
  if (first_free > nv)
    throw UsageError("odt_smooth: first free vertex " + std::to_string(first_free) + " beyond the " +
                     std::to_string(nv) + " vertices");
  TetSmoothResult r;
  if (first_free == nv) return r;
  // Tetrahedra around each free vertex (compressed rows).
  std::vector<std::size_t> start(nv - first_free + 1, 0);
  for (const auto& c : t.tets)
    for (int v : c)
      if (std::size_t(v) >= first_free) ++start[std::size_t(v) - first_free + 1];
  for (std::size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
  std::vector<std::size_t> ring(start.back()), fill(start.begin(), start.end() - 1);
  for (std::size_t k = 0; k < t.tets.size(); ++k)
    for (int v : t.tets[k])
      if (std::size_t(v) >= first_free) ring[fill[std::size_t(v) - first_free]++] = k;

  auto& X = t.vertices;
  // The worst tetrahedra around vertex i with i at x: smallest radius ratio
  // (-1 when one is not positive) and the extreme dihedral angles.
  struct Worst {
    double rr = 1, dmin = 180, dmax = 0;
  };
  auto worst = [&](std::size_t i, const Vec3& x) {
    Worst w;
    for (std::size_t s = start[i - first_free]; s < start[i - first_free + 1]; ++s) {
      const auto& c = t.tets[ring[s]];
      Vec3 q[4];
      for (int k = 0; k < 4; ++k) q[k] = std::size_t(c[std::size_t(k)]) == i ? x : X[std::size_t(c[std::size_t(k)])];
      if (!(volume6(q[0], q[1], q[2], q[3]) > 0)) {
        w.rr = -1;
        return w;
      }
      w.rr = std::min(w.rr, tet_radius_ratio(q[0], q[1], q[2], q[3]));
      const DihedralRange d = tet_dihedral_range(q[0], q[1], q[2], q[3]);
      w.dmin = std::min(w.dmin, d.min);
      w.dmax = std::max(w.dmax, d.max);
    }
    return w;
  };
  // A move may not lower the worst radius ratio, nor take an angle below
  // min(the old smallest, kLow) or above max(the old largest, kHigh): the
  // mesh's extreme angles never get worse and the [25, 140] band is kept.
  constexpr double kLow = 25, kHigh = 140;
  auto acceptable = [&](const Worst& now, const Worst& old) {
    return now.rr >= old.rr && now.dmin >= std::min(old.dmin, kLow) && now.dmax <= std::max(old.dmax, kHigh);
  };
  const std::size_t nfree = nv - first_free;
  // Colour the free vertices so that no two of a colour share a tetrahedron
  // (greedy, in vertex order): the vertices of one colour move independently
  // of each other, in parallel, with the same result for any thread count.
  std::vector<int> colour(nfree, -1);
  int colours = 0;
  {
    std::vector<std::size_t> taken;  // colour -> the vertex that last saw it taken
    for (std::size_t i = first_free; i < nv; ++i) {
      for (std::size_t s = start[i - first_free]; s < start[i - first_free + 1]; ++s)
        for (int v : t.tets[ring[s]]) {
          if (std::size_t(v) < first_free || std::size_t(v) == i) continue;
          const int c = colour[std::size_t(v) - first_free];
          if (c >= 0) taken[std::size_t(c)] = i;
        }
      int c = 0;
      while (c < colours && taken[std::size_t(c)] == i) ++c;
      if (c == colours) {
        ++colours;
        taken.push_back(nv);
      }
      colour[i - first_free] = c;
    }
  }
  std::vector<std::size_t> by_colour_start(std::size_t(colours) + 1, 0), by_colour(nfree);
  for (int c : colour) ++by_colour_start[std::size_t(c) + 1];
  for (std::size_t c = 1; c < by_colour_start.size(); ++c) by_colour_start[c] += by_colour_start[c - 1];
  {
    std::vector<std::size_t> fill_c(by_colour_start.begin(), by_colour_start.end() - 1);
    for (std::size_t i = 0; i < nfree; ++i) by_colour[fill_c[std::size_t(colour[i])]++] = first_free + i;
  }
  // One vertex's ODT move: 1 moved, 0 rejected, -1 nothing to do.
  auto move = [&](std::size_t i) -> int {
    if (start[i - first_free] == start[i - first_free + 1]) return -1;  // in no tetrahedron
    double vol = 0;
    Vec3 acc(0, 0, 0);
    for (std::size_t s = start[i - first_free]; s < start[i - first_free + 1]; ++s) {
      const auto& c = t.tets[ring[s]];
      const Vec3 &a = X[std::size_t(c[0])], &b = X[std::size_t(c[1])], &cc = X[std::size_t(c[2])],
                 &d = X[std::size_t(c[3])];
      const double det = volume6(a, b, cc, d);
      if (!(det > 0)) continue;
      acc += circumcentre(a, b, cc, d, det) * det;
      vol += det;
    }
    if (!(vol > 0)) return -1;
    const Vec3 target = acc / vol, old = X[i];
    const Worst w0 = worst(i, old);
    for (double step : {1.0, 0.5}) {
      const Vec3 x = old + (target - old) * step;
      if (!is_finite(x)) continue;
      if (acceptable(worst(i, x), w0)) {
        X[i] = x;
        return 1;
      }
    }
    return 0;
  };
  Stopwatch odt_clock;
  for (int sweep = 0; sweep < p.sweeps; ++sweep) {
    std::size_t moved = 0;
    for (int c = 0; c < colours; ++c) {
      const std::size_t b0 = by_colour_start[std::size_t(c)], b1 = by_colour_start[std::size_t(c) + 1];
      const auto counts = tbb::parallel_reduce(
          tbb::blocked_range<std::size_t>(b0, b1, 256), std::array<std::size_t, 2>{0, 0},
          [&](const tbb::blocked_range<std::size_t>& rg, std::array<std::size_t, 2> n) {
            for (std::size_t k = rg.begin(); k != rg.end(); ++k) {
              const int m = move(by_colour[k]);
              if (m == 1) ++n[0];
              if (m == 0) ++n[1];
            }
            return n;
          },
          [](std::array<std::size_t, 2> x, const std::array<std::size_t, 2>& y) {
            return std::array<std::size_t, 2>{x[0] + y[0], x[1] + y[1]};
          });
      moved += counts[0];
      r.moves += counts[0];
      r.rejected += counts[1];
    }
    ++r.sweeps;
    if (double(moved) < p.stop_fraction * double(nfree)) break;
  }
  r.odt_seconds = odt_clock.seconds();
  if (p.perturb_below <= 0 && p.perturb_above >= 180) return r;
  Stopwatch perturb_clock;
  // Sliver perturbation: each free vertex of a tetrahedron outside
  // [perturb_below, perturb_above] climbs to raise the worst angle margin
  // min(smallest dihedral / below, (180° - largest) / (180° - above)) among
  // its tetrahedra: compass
  // search over 14 directions, the step halved when none improves. The two
  // margins are relative to their bounds, so fixing a small angle cannot
  // open a large one past its bound (nor the other way).
  constexpr double kRatioFloor = 0.25;
  const double low = std::max(p.perturb_below, 1.0), high = std::max(180 - p.perturb_above, 1.0);
  // The margin of the worst tetrahedron is that of the ring's extreme angles
  // (both terms are monotone in them); -1 when a tetrahedron is not positive.
  auto margin = [&](const Worst& w) { return w.rr < 0 ? -1.0 : std::min(w.dmin / low, (180 - w.dmax) / high); };
  std::vector<Vec3> dirs;
  for (int a = 0; a < 3; ++a)
    for (double sgn : {-1.0, 1.0}) {
      Vec3 e(0, 0, 0);
      e[a] = sgn;
      dirs.push_back(e);
    }
  for (double x : {-1.0, 1.0})
    for (double y : {-1.0, 1.0})
      for (double z : {-1.0, 1.0}) dirs.push_back(Vec3(x, y, z) / std::sqrt(3.0));
  std::vector<std::size_t> todo;
  for (const auto& c : t.tets) {
    const DihedralRange d =
        tet_dihedral_range(X[std::size_t(c[0])], X[std::size_t(c[1])], X[std::size_t(c[2])], X[std::size_t(c[3])]);
    if (d.min >= p.perturb_below && d.max <= p.perturb_above) continue;
    for (int v : c)
      if (std::size_t(v) >= first_free) todo.push_back(std::size_t(v));
  }
  std::sort(todo.begin(), todo.end());
  todo.erase(std::unique(todo.begin(), todo.end()), todo.end());
  r.perturb_candidates = todo.size();
  for (std::size_t i : todo) {
    double shortest = 1e300;
    for (std::size_t s = start[i - first_free]; s < start[i - first_free + 1]; ++s)
      for (int v : t.tets[ring[s]])
        if (std::size_t(v) != i) shortest = std::min(shortest, norm(X[std::size_t(v)] - X[i]));
    const Worst w0 = worst(i, X[i]);
    double step = 0.2 * shortest, best = margin(w0);
    // The radius ratio around the vertex may not fall below min(its old worst, kRatioFloor).
    const double rr_floor = std::min(w0.rr, kRatioFloor);
    bool improved = false;
    for (int it = 0; it < 40 && step > 1e-3 * shortest; ++it) {
      bool found = false;
      for (const Vec3& e : dirs) {
        const Vec3 x = X[i] + e * step;
        const Worst w = worst(i, x);
        const double m = margin(w);
        if (m > best && w.rr >= rr_floor) {
          best = m;
          X[i] = x;
          found = improved = true;
        }
      }
      if (!found) step *= 0.5;
    }
    r.perturbed += improved;
  }
  r.perturb_seconds = perturb_clock.seconds();
  return r;
}

}  // namespace pm
