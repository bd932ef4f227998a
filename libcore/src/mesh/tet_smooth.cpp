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
  return r;
}

}  // namespace pm
