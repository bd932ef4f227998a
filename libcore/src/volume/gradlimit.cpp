#include "pm/volume/gradlimit.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <vector>

#include "pm/base/error.h"

namespace pm {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Grid {
  Dims d;
  std::size_t sy = 0, sz = 0;
  Mat3 metric;  // D^T D: squared world length of an index step is s^T metric s
  double spacing[3] = {1, 1, 1};
  explicit Grid(const Volume& v) : d(v.dims()), sy(d.nx), sz(d.nx * d.ny) {
    const Mat3& D = v.geometry().directions;
    metric = transpose(D) * D;
    for (int a = 0; a < 3; ++a) spacing[a] = v.geometry().spacing(a);
    for (int r = 0; r < 3; ++r)
      for (int q = 0; q < 3; ++q) diagonal &= r == q || metric.m[r][q] == 0.0;
  }
  void ijk(std::size_t v, long& i, long& j, long& k) const {
    i = long(v % d.nx);
    j = long((v / d.nx) % d.ny);
    k = long(v / sz);
  }
  bool diagonal = true;
  double dist(long di, long dj, long dk) const {
    if (diagonal) {
      const double x = double(di) * spacing[0], y = double(dj) * spacing[1], z = double(dk) * spacing[2];
      return std::sqrt(x * x + y * y + z * z);
    }
    const double s[3] = {double(di), double(dj), double(dk)};
    double q = 0;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) q += s[r] * metric.m[r][c] * s[c];
    return std::sqrt(std::max(0.0, q));
  }
};

/// Label-correcting propagation: a voxel offers its source to all 26
/// neighbours every time its value has dropped since its last offer, so when
/// nothing is left to offer every pair of neighbours x, y satisfies
/// h(y) <= h(x) + delta |x - y| (triangle inequality through x's source),
/// whatever the processing order. The order only decides how often a voxel
/// is processed again: an approximate increasing-value order from a bucket
/// queue (width 2 delta * smallest spacing, each bucket in index order for
/// memory locality) keeps that rare; the bucket width changes the run time,
/// not the result's accuracy (measured). With `known_only`, sources travel
/// through known voxels only (h0 < inf), and unknown voxels stay unknown
/// (+inf): an upper bound of the full result on every known voxel, at the
/// cost of the known voxels alone.
std::vector<double> propagate(const Grid& g, const std::vector<double>& h0, double delta, double ceiling,
                              bool known_only = false) {
  const std::size_t n = h0.size();
  // 8 bytes per voxel so that neighbours cost as few cache misses as possible:
  // h as float (the output is float unless the input was double; relative
  // rounding 6e-8), the source index and a "value dropped since the last
  // offer" flag in its top bit.
  struct Cell {
    float h;
    std::uint32_t src;  // bit 31: dirty
  };
  constexpr std::uint32_t kDirty = 0x80000000u, kIndex = 0x7FFFFFFFu;
  std::vector<Cell> c(n);
  double lo = kInf, hi = 0;
  for (std::size_t v = 0; v < n; ++v) {
    c[v] = {h0[v] < kInf ? float(h0[v]) : std::numeric_limits<float>::infinity(),
            std::uint32_t(v) | (h0[v] < kInf ? kDirty : 0u)};
    if (h0[v] < kInf) {
      lo = std::min(lo, h0[v]);
      hi = std::max(hi, h0[v]);
    }
  }
  // Values never exceed the largest known value plus delta times the grid diagonal.
  const double top = hi + delta * g.dist(long(g.d.nx), long(g.d.ny), long(g.d.nz));
  const double min_spacing = std::min({g.spacing[0], g.spacing[1], g.spacing[2]});
  const std::size_t max_buckets = std::size_t(1) << 20;
  const double width = std::max(2.0 * delta * min_spacing, (top - lo) / double(max_buckets - 1));
  const std::size_t nb = std::size_t((top - lo) / width) + 2;
  std::vector<std::vector<std::uint32_t>> buckets(nb);
  std::size_t current = 0;
  auto bucket_of = [&](double key) {
    const std::size_t b = std::size_t(std::max(0.0, (key - lo) / width));
    return std::min(nb - 1, std::max(current, b));
  };
  for (std::size_t v = 0; v < n; ++v)
    if (c[v].src & kDirty) buckets[bucket_of(h0[v])].push_back(std::uint32_t(v));
  const long nx = long(g.d.nx), ny = long(g.d.ny), nz = long(g.d.nz);
  std::vector<std::uint32_t> batch;
  for (current = 0; current < nb; ++current) {
    // Voxels pushed into the current bucket while it is processed come back in
    // the next round; each round runs in index order for memory locality.
    while (!buckets[current].empty()) {
      batch.swap(buckets[current]);
      buckets[current].clear();
      std::sort(batch.begin(), batch.end());
      for (const std::uint32_t v : batch) {
        if (!(c[v].src & kDirty)) continue;
        c[v].src &= kIndex;
        const std::uint32_t s = c[v].src;
        const double hs = h0[s];
        long si, sj, sk, i, j, k;
        g.ijk(s, si, sj, sk);
        g.ijk(v, i, j, k);
        for (long dk = -1; dk <= 1; ++dk) {
          const long kk = k + dk;
          if (kk < 0 || kk >= nz) continue;
          for (long dj = -1; dj <= 1; ++dj) {
            const long jj = j + dj;
            if (jj < 0 || jj >= ny) continue;
            Cell* row = c.data() + g.sy * std::size_t(jj) + g.sz * std::size_t(kk);
            for (long di = -1; di <= 1; ++di) {
              const long ii = i + di;
              if (ii < 0 || ii >= nx || (di == 0 && dj == 0 && dk == 0)) continue;
              Cell& u = row[ii];
              if ((u.src & kIndex) == s) continue;  // already holds this source
              if (known_only && !(h0[std::size_t(&u - c.data())] < kInf)) continue;
              // Compare as stored (float): a strict decrease of the stored
              // value on every update is what makes the loop terminate.
              const float cand = float(hs + delta * g.dist(ii - si, jj - sj, kk - sk));
              if (cand < u.h && cand < ceiling) {
                u.h = cand;
                u.src = s | kDirty;
                buckets[bucket_of(cand)].push_back(std::uint32_t(&u - c.data()));
              }
            }
          }
        }
      }
      batch.clear();
    }
    std::vector<std::uint32_t>().swap(buckets[current]);
  }
  std::vector<double> h(n);
  for (std::size_t v = 0; v < n; ++v)
    h[v] = std::min({double(c[v].h), h0[v], ceiling});  // rounding never raises h
  return h;
}

/// Persson's explicit upwind iteration (SPEC §5). Returns the number of sweeps.
std::size_t upwind(const Grid& g, std::vector<double>& h, double delta, double tolerance, std::size_t max_iter) {
  const std::size_t n = h.size();
  // Monotone (stable) when dt dG/dh(v) <= 1; by Cauchy-Schwarz
  // dG/dh(v) <= sqrt(2 sum_a 1/s_a^2), since both sides of an axis may count.
  double inv2 = 0;
  for (double s : g.spacing) inv2 += 1.0 / (s * s);
  const double dt = 0.9 / std::sqrt(2 * inv2);
  const std::size_t stride[3] = {1, g.sy, g.sz};
  const std::size_t size[3] = {g.d.nx, g.d.ny, g.d.nz};
  std::vector<double> next(n);
  for (std::size_t it = 1; it <= max_iter; ++it) {
    const double change = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, g.d.nz), 0.0,
        [&](const tbb::blocked_range<std::size_t>& r, double acc) {
          for (std::size_t k = r.begin(); k != r.end(); ++k)
            for (std::size_t j = 0; j < g.d.ny; ++j)
              for (std::size_t i = 0; i < g.d.nx; ++i) {
                const std::size_t v = i + g.sy * j + g.sz * k;
                const std::size_t c[3] = {i, j, k};
                double G2 = 0;
                for (int a = 0; a < 3; ++a) {
                  const double dm = c[a] > 0 ? (h[v] - h[v - stride[a]]) / g.spacing[a] : 0.0;
                  const double dp = c[a] + 1 < size[a] ? (h[v + stride[a]] - h[v]) / g.spacing[a] : 0.0;
                  G2 += std::pow(std::max(dm, 0.0), 2) + std::pow(std::min(dp, 0.0), 2);
                }
                const double G = std::sqrt(G2);
                next[v] = h[v] + dt * (std::min(G, delta) - G);
                acc = std::max(acc, std::fabs(next[v] - h[v]) / h[v]);
              }
          return acc;
        },
        [](double a, double b) { return std::max(a, b); });
    h.swap(next);
    if (change < tolerance) return it;
  }
  std::ostringstream m;
  m << "gradient_limit: the upwind iteration did not reach a relative change < " << tolerance << " in "
    << max_iter << " sweeps; use the propagate method or a larger tolerance";
  throw InputError(m.str());
}

double max_slope(const Grid& g, const std::vector<double>& h) {
  const std::size_t stride[3] = {1, g.sy, g.sz};
  const std::size_t size[3] = {g.d.nx, g.d.ny, g.d.nz};
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, g.d.nz), 0.0,
      [&](const tbb::blocked_range<std::size_t>& r, double acc) {
        for (std::size_t k = r.begin(); k != r.end(); ++k)
          for (std::size_t j = 0; j < g.d.ny; ++j)
            for (std::size_t i = 0; i < g.d.nx; ++i) {
              const std::size_t v = i + g.sy * j + g.sz * k;
              const std::size_t c[3] = {i, j, k};
              for (int a = 0; a < 3; ++a)
                if (c[a] + 1 < size[a])
                  acc = std::max(acc, std::fabs(h[v + stride[a]] - h[v]) / g.spacing[a]);
            }
        return acc;
      },
      [](double a, double b) { return std::max(a, b); });
}

}  // namespace

GradLimitResult gradient_limit(const Volume& in, const GradLimitParams& p) {
  if (!(p.delta > 0) || !std::isfinite(p.delta)) {
    std::ostringstream m;
    m << "gradient_limit: delta " << p.delta << "; expected a finite gradient bound > 0 (e.g. 0.3)";
    throw UsageError(m.str());
  }
  if (!(p.ceiling > 0)) {
    std::ostringstream m;
    m << "gradient_limit: ceiling " << p.ceiling << "; expected > 0 (world units; +inf = none)";
    throw UsageError(m.str());
  }
  if (!(p.tolerance > 0)) {
    std::ostringstream m;
    m << "gradient_limit: tolerance " << p.tolerance << "; expected > 0 (e.g. 1e-5)";
    throw UsageError(m.str());
  }
  if (is_integer(in.type()))
    throw InputError(std::string("gradient_limit: voxel type ") + voxel_type_name(in.type()) +
                     " is an integer type (a label map?); expected a float sizing field h in world units");
  if (in.count() >= (std::size_t(1) << 31))
    throw InputError("gradient_limit: volume has " + std::to_string(in.count()) + " voxels; at most 2^31 - 1 supported");
  const Grid g(in);
  std::vector<double> h0 = in.to_double();
  GradLimitResult res;
  double hmax = 0;
  for (std::size_t v = 0; v < h0.size(); ++v) {
    const double x = h0[v];
    if (!std::isfinite(x) && !p.nonfinite_unknown) {
      long i, j, k;
      g.ijk(v, i, j, k);
      std::ostringstream m;
      m << "gradient_limit: voxel (" << i << "," << j << "," << k << ") is " << x
        << "; expected finite values (h <= 0 marks unknown voxels)";
      throw InputError(m.str());
    }
    if (std::isfinite(x) && x > 0) {
      ++res.known;
      hmax = std::max(hmax, x);
    } else {
      h0[v] = kInf;
      ++res.unknown;
    }
  }
  if (res.known == 0)
    throw InputError("gradient_limit: no voxel has a finite h > 0; expected a sizing field with positive values "
                     "(h <= 0 marks unknown voxels)");

  double ceiling = p.ceiling;
  if (p.flat_far_field) {
    // The known voxels' limited values are at most what limiting among the
    // known voxels alone gives (fewer paths): its largest value bounds them
    // all, far below the largest h0 where a few known voxels sit high (frog,
    // 5 materials: 9.0 against 73.4, and 1.4M of 4.3M voxels below the cap
    // instead of nearly all).
    const std::vector<double> hk = propagate(g, h0, p.delta, ceiling, true);
    double kmax = 0;
    for (std::size_t v = 0; v < hk.size(); ++v)
      if (h0[v] < kInf) kmax = std::max(kmax, hk[v]);
    ceiling = std::min(ceiling, kmax + 2 * p.delta * g.dist(1, 1, 1));  // kmax <= hmax: limiting only lowers
  }
  res.cap = ceiling;
  std::vector<double> h;
  if (p.method == GradLimitMethod::propagate) {
    h = propagate(g, h0, p.delta, ceiling);
    res.iterations = 1;
  } else {
    // Unknown voxels start above any value the extension can take.
    const Box b = in.world_bounds();
    const double cap = hmax + p.delta * norm(b.size()) * 1.01 + 1e-12;
    h = h0;
    for (double& x : h)
      if (x == kInf) x = cap;
    res.iterations = upwind(g, h, p.delta, p.tolerance, p.max_iterations);
    for (double& x : h) x = std::min(x, ceiling);
  }
  for (std::size_t v = 0; v < h.size(); ++v)
    if (h0[v] < kInf && h[v] < h0[v]) ++res.lowered;
  res.max_slope_ratio = max_slope(g, h) / p.delta;
  res.h = Volume(in.type() == VoxelType::f64 ? VoxelType::f64 : VoxelType::f32, in.dims(), in.geometry());
  for (std::size_t v = 0; v < h.size(); ++v) res.h.set(v, h[v]);
  return res;
}

GradLimitResult interior_sizing(const Volume& h, const std::vector<Vec3>& boundary, double band, double delta,
                                double max_size) {
  if (!(band > 0)) throw UsageError("interior sizing: band " + std::to_string(band) + " must be > 0 (world units)");
  if (!(delta > 0)) throw UsageError("interior sizing: delta " + std::to_string(delta) + " must be > 0");
  if (!(max_size >= 0))
    throw UsageError("interior sizing: max size " + std::to_string(max_size) + " must be > 0 (world units; 0 = no cap)");
  const Dims& d = h.dims();
  const Geometry& g = h.geometry();
  // Voxel radius of the band (directions may be oblique: bound it by the
  // smallest spacing).
  const double smin = std::min({g.spacing(0), g.spacing(1), g.spacing(2)});
  const long reach = long(std::ceil(band / smin)) + 1;
  std::vector<char> keep(h.count(), 0);
  for (const Vec3& x : boundary) {
    if (!is_finite(x)) continue;
    const Vec3 c = g.world_to_index(x);
    const long ci = long(std::lround(c.x)), cj = long(std::lround(c.y)), ck = long(std::lround(c.z));
    for (long k = std::max(0L, ck - reach); k <= std::min(long(d.nz) - 1, ck + reach); ++k)
      for (long j = std::max(0L, cj - reach); j <= std::min(long(d.ny) - 1, cj + reach); ++j)
        for (long i = std::max(0L, ci - reach); i <= std::min(long(d.nx) - 1, ci + reach); ++i)
          if (norm2(g.index_to_world(Vec3{double(i), double(j), double(k)}) - x) <= band * band)
            keep[h.index(std::size_t(i), std::size_t(j), std::size_t(k))] = 1;
  }
  Volume masked(VoxelType::f32, d, g);
  std::size_t kept = 0;
  double kept_max = 0;
  for (std::size_t v = 0; v < h.count(); ++v) {
    const double hv = h.get(v);
    const bool k = keep[v] && std::isfinite(hv) && hv > 0;
    masked.set(v, k ? hv : 0.0);
    kept += k;
    if (k) kept_max = std::max(kept_max, hv);
  }
  if (kept == 0)
    throw InputError("interior sizing: no boundary point lies within " + std::to_string(band) +
                     " world units of a voxel with h > 0; expected the surface inside the sizing field's box");
  GradLimitParams p;
  p.delta = delta;
  p.ceiling = max_size > 0 ? max_size : kept_max;  // the propagation stops there
  GradLimitResult r = gradient_limit(masked, p);
  r.cap = p.ceiling;
  return r;
}

}  // namespace pm
