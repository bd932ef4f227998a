#include "pm/mesh/tet_smooth.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "pm/base/error.h"
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
      const std::array<double, 6> d = tet_dihedrals(q[0], q[1], q[2], q[3]);
      const auto [lo, hi] = std::minmax_element(d.begin(), d.end());
      w.dmin = std::min(w.dmin, *lo);
      w.dmax = std::max(w.dmax, *hi);
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
  for (int sweep = 0; sweep < p.sweeps; ++sweep) {
    std::size_t moved = 0;
    for (std::size_t i = first_free; i < nv; ++i) {
      if (start[i - first_free] == start[i - first_free + 1]) continue;  // in no tetrahedron
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
      if (!(vol > 0)) continue;
      const Vec3 target = acc / vol, old = X[i];
      const Worst w0 = worst(i, old);
      bool done = false;
      for (double step : {1.0, 0.5}) {
        const Vec3 x = old + (target - old) * step;
        if (!is_finite(x)) continue;
        if (acceptable(worst(i, x), w0)) {
          X[i] = x;
          done = true;
          break;
        }
      }
      if (done) {
        ++moved;
        ++r.moves;
      } else {
        ++r.rejected;
      }
    }
    ++r.sweeps;
    if (double(moved) < p.stop_fraction * double(nfree)) break;
  }
  if (p.perturb_below <= 0 && p.perturb_above >= 180) return r;
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
    const std::array<double, 6> d = tet_dihedrals(X[std::size_t(c[0])], X[std::size_t(c[1])], X[std::size_t(c[2])],
                                                  X[std::size_t(c[3])]);
    const auto [lo, hi] = std::minmax_element(d.begin(), d.end());
    if (*lo >= p.perturb_below && *hi <= p.perturb_above) continue;
    for (int v : c)
      if (std::size_t(v) >= first_free) todo.push_back(std::size_t(v));
  }
  std::sort(todo.begin(), todo.end());
  todo.erase(std::unique(todo.begin(), todo.end()), todo.end());
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
  return r;
}

}  // namespace pm
