#include "pm/volume/tighten.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>

#include "pm/base/cpu.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/parallel.h"
#include "pm/base/stats.h"
#include "pm/field/distance.h"

#if PM_AVX2_COPIES
#include <immintrin.h>
#endif

namespace pm {

TightenDefaults tighten_defaults(const Volume& v, double radius, int upsample) {
  TightenDefaults d;
  const Dims n = v.dims();
  const std::size_t smallest = std::min({n.nx, n.ny, n.nz});
  const bool auto_k = upsample <= 0;
  d.upsample = upsample;
  if (auto_k) {
    d.upsample = 1;
    if (smallest > 0 && smallest < kTightenMinVoxels)
      d.upsample = int(std::min<std::size_t>(8, (2 * kTightenMinVoxels + smallest - 1) / smallest));
  }
  d.radius = radius;
  if (!(radius > 0)) {
    const Geometry g = v.geometry();
    d.radius = std::max({g.spacing(0), g.spacing(1), g.spacing(2)});
    if (auto_k) d.radius /= double(d.upsample);
  }
  return d;
}


std::vector<std::uint8_t> binary_mask_inside(const Volume& mask, const std::string& what) {
  const std::size_t n = mask.count();
  if (n == 0) throw InputError(what + ": the volume has no voxels");
  // uint8 masks (tighten_labels' per-label masks among them) read directly.
  const std::uint8_t* u8 = mask.type() == VoxelType::u8 ? mask.data<std::uint8_t>() : nullptr;
  auto get = [&](std::size_t c) { return u8 ? double(u8[c]) : mask.get(c); };
  const double a = get(0);
  double b = a;
  bool two = false;
  for (std::size_t c = 1; c < n; ++c) {
    const double v = get(c);
    if (v == a || (two && v == b)) continue;
    if (!two) {
      b = v;
      two = true;
      continue;
    }
    // A third value: count them all (up to a cap) for the message.
    constexpr std::size_t kCap = 65536;
    std::set<double> values;
    bool nan = false;
    for (std::size_t d = 0; d < n && values.size() < kCap; ++d) {
      const double w = get(d);
      if (std::isnan(w)) nan = true;
      else values.insert(w);
    }
    const std::size_t count = values.size() + (nan ? 1 : 0);
    std::ostringstream m;
    m << what << ": expected a binary mask (2 distinct values), got "
      << (values.size() >= kCap ? "more than " + std::to_string(kCap - 1) : std::to_string(count)) << " values ("
      << voxel_type_name(mask.type()) << ", range " << *values.begin() << " to " << *values.rbegin() << ")";
    throw InputError(m.str());
  }
  if (!two) {
    std::ostringstream m;
    m << what << ": empty mask: every voxel is " << a << "; expected inside and outside voxels (2 distinct values)";
    throw InputError(m.str());
  }
  const double in = std::max(a, b);
  std::vector<std::uint8_t> inside(n);
  for (std::size_t c = 0; c < n; ++c) inside[c] = get(c) == in ? 1 : 0;
  return inside;
}

// tighten_labels: bytes a label in flight holds per padded, upsampled voxel
// (measured peak), and the memory the labels beyond the first may add.
constexpr double kTightenBytesPerVoxel = 56.0;
constexpr double kTightenSideBySideBytes = 1024.0 * 1024.0 * 1024.0;

namespace {

// The flowing band: the active nodes (working-box indices, ascending) and
// the offsets of their 18 stencil neighbours (faces and edges of the 3x3x3
// block) in flow_step's order: x+ x- y+ y- z+ z-, then the xy, xz and yz
// edge quadruples (+ +, + -, - +, - -). The flow reads the neighbours in the
// working box itself: the active nodes come in grid order, so the rows a
// node reads are the ones its predecessors read (a thin shell touches few
// lines of three slices), and no table of references has to be streamed.
struct Band {
  static constexpr int kRefs = 18;
  const std::vector<std::uint32_t>& active;
  std::ptrdiff_t off[kRefs];
  Band(const std::vector<std::uint32_t>& a, const Dims& d) : active(a) {
    const std::ptrdiff_t sx = 1, sy = std::ptrdiff_t(d.nx), sz = std::ptrdiff_t(d.nx * d.ny);
    const std::ptrdiff_t o[kRefs] = {sx,       -sx,      sy,       -sy,      sz,       -sz,
                                     sx + sy,  sx - sy,  -sx + sy, -sx - sy, sx + sz,  sx - sz,
                                     -sx + sz, -sx - sz, sy + sz,  sy - sz,  -sy + sz, -sy - sz};
    std::copy(o, o + kRefs, off);
  }
  std::size_t size() const { return active.size(); }
};

// The flow's update at one active node (see flow_step): the new value,
// clamped between lo and hi, in double.
inline double flow_value(const float* r, const std::ptrdiff_t* o, double ix, double iy, double iz, double dt,
                         float lo, float hi) {
  const double f = r[0];
  const double fxp = r[o[0]], fxm = r[o[1]], fyp = r[o[2]], fym = r[o[3]];
  const double fzp = r[o[4]], fzm = r[o[5]];
  const double px = 0.5 * (fxp - fxm) * ix, py = 0.5 * (fyp - fym) * iy, pz = 0.5 * (fzp - fzm) * iz;
  const double pxx = (fxp - 2 * f + fxm) * ix * ix, pyy = (fyp - 2 * f + fym) * iy * iy,
               pzz = (fzp - 2 * f + fzm) * iz * iz;
  const double pxy = 0.25 * (r[o[6]] - r[o[7]] - r[o[8]] + r[o[9]]) * ix * iy;
  const double pxz = 0.25 * (r[o[10]] - r[o[11]] - r[o[12]] + r[o[13]]) * ix * iz;
  const double pyz = 0.25 * (r[o[14]] - r[o[15]] - r[o[16]] + r[o[17]]) * iy * iz;
  const double gx2 = px * px, gy2 = py * py, gz2 = pz * pz, g2 = gx2 + gy2 + gz2;
  const double num = pxx * (gy2 + gz2) + pyy * (gx2 + gz2) + pzz * (gx2 + gy2) -
                     2 * (px * py * pxy + px * pz * pxz + py * pz * pyz);
  const double v = f + dt * num / (g2 + 1e-12);
  return std::min(std::max(v, double(lo)), double(hi));
}

// How far the zero set moved at node r (new value v): |v - f| where a face
// neighbour lies across it and |f| < near, else 0.
inline double zero_set_move(const float* r, const std::ptrdiff_t* o, double v, double near) {
  const double f = r[0];
  const bool neg = f < 0;
  bool across = false;
  for (int k = 0; k < 6; ++k) across |= (r[o[k]] < 0) != neg;
  return std::fabs(f) < near && across ? std::fabs(v - f) : 0.0;
}

#if PM_AVX2_COPIES
#define PM_AVX2 __attribute__((target("avx2")))
// Four floats at c[0..3] + off, widened to double: plain loads when the four
// nodes are consecutive along x, else a gather.
PM_AVX2 inline __m256d flow_at_x4(const float* cur, const std::uint32_t* c, __m128i idx, bool run,
                                  std::ptrdiff_t off) {
  if (run) return _mm256_cvtps_pd(_mm_loadu_ps(cur + c[0] + off));
  return _mm256_cvtps_pd(_mm_i32gather_ps(cur, _mm_add_epi32(idx, _mm_set1_epi32(std::int32_t(off))), 4));
}
PM_AVX2 inline __m128 flow_at_x4f(const float* cur, const std::uint32_t* c, __m128i idx, bool run,
                                  std::ptrdiff_t off) {
  if (run) return _mm_loadu_ps(cur + c[0] + off);
  return _mm_i32gather_ps(cur, _mm_add_epi32(idx, _mm_set1_epi32(std::int32_t(off))), 4);
}
// ((a - b) - c) + d in float, widened: flow_value's edge sums.
PM_AVX2 inline __m256d flow_edge_x4(const float* cur, const std::uint32_t* c, __m128i idx, bool run,
                                    const std::ptrdiff_t* o) {
  const __m128 s =
      _mm_add_ps(_mm_sub_ps(_mm_sub_ps(flow_at_x4f(cur, c, idx, run, o[0]), flow_at_x4f(cur, c, idx, run, o[1])),
                            flow_at_x4f(cur, c, idx, run, o[2])),
                 flow_at_x4f(cur, c, idx, run, o[3]));
  return _mm256_cvtps_pd(s);
}

// flow_value at four active nodes c[0..3] (AVX2, chosen at run time): the
// same IEEE operations in the same order on every lane (the edge sums in
// float, no FMA), so the same doubles; written to next as floats. Returns
// the largest zero_set_move of the four (NaN moves ignored, as std::max
// ignores them there).
PM_AVX2 double flow_values_x4(const float* cur, float* next, const std::uint32_t* c, const std::ptrdiff_t* o,
                              double ix, double iy, double iz, double dt, const float* lo, const float* hi,
                              double near) {
  const bool run = c[3] == c[0] + 3 && c[1] == c[0] + 1 && c[2] == c[0] + 2;
  const __m128i idx = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c));
  const __m256d f = flow_at_x4(cur, c, idx, run, 0);
  const __m256d fxp = flow_at_x4(cur, c, idx, run, o[0]), fxm = flow_at_x4(cur, c, idx, run, o[1]);
  const __m256d fyp = flow_at_x4(cur, c, idx, run, o[2]), fym = flow_at_x4(cur, c, idx, run, o[3]);
  const __m256d fzp = flow_at_x4(cur, c, idx, run, o[4]), fzm = flow_at_x4(cur, c, idx, run, o[5]);
  const __m256d half = _mm256_set1_pd(0.5), two = _mm256_set1_pd(2.0), quarter = _mm256_set1_pd(0.25);
  const __m256d vx = _mm256_set1_pd(ix), vy = _mm256_set1_pd(iy), vz = _mm256_set1_pd(iz);
  const __m256d px = _mm256_mul_pd(_mm256_mul_pd(half, _mm256_sub_pd(fxp, fxm)), vx);
  const __m256d py = _mm256_mul_pd(_mm256_mul_pd(half, _mm256_sub_pd(fyp, fym)), vy);
  const __m256d pz = _mm256_mul_pd(_mm256_mul_pd(half, _mm256_sub_pd(fzp, fzm)), vz);
  const __m256d f2 = _mm256_mul_pd(two, f);
  const __m256d pxx = _mm256_mul_pd(_mm256_mul_pd(_mm256_add_pd(_mm256_sub_pd(fxp, f2), fxm), vx), vx);
  const __m256d pyy = _mm256_mul_pd(_mm256_mul_pd(_mm256_add_pd(_mm256_sub_pd(fyp, f2), fym), vy), vy);
  const __m256d pzz = _mm256_mul_pd(_mm256_mul_pd(_mm256_add_pd(_mm256_sub_pd(fzp, f2), fzm), vz), vz);
  const __m256d pxy =
      _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(quarter, flow_edge_x4(cur, c, idx, run, o + 6)), vx), vy);
  const __m256d pxz =
      _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(quarter, flow_edge_x4(cur, c, idx, run, o + 10)), vx), vz);
  const __m256d pyz =
      _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(quarter, flow_edge_x4(cur, c, idx, run, o + 14)), vy), vz);
  const __m256d gx2 = _mm256_mul_pd(px, px), gy2 = _mm256_mul_pd(py, py), gz2 = _mm256_mul_pd(pz, pz);
  const __m256d g2 = _mm256_add_pd(_mm256_add_pd(gx2, gy2), gz2);
  const __m256d a = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(pxx, _mm256_add_pd(gy2, gz2)),
                                                _mm256_mul_pd(pyy, _mm256_add_pd(gx2, gz2))),
                                  _mm256_mul_pd(pzz, _mm256_add_pd(gx2, gy2)));
  const __m256d b = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_mul_pd(px, py), pxy),
                                                _mm256_mul_pd(_mm256_mul_pd(px, pz), pxz)),
                                  _mm256_mul_pd(_mm256_mul_pd(py, pz), pyz));
  const __m256d num = _mm256_sub_pd(a, _mm256_mul_pd(two, b));
  __m256d v = _mm256_add_pd(
      f, _mm256_div_pd(_mm256_mul_pd(_mm256_set1_pd(dt), num), _mm256_add_pd(g2, _mm256_set1_pd(1e-12))));
  // std::max(v, lo) is (v < lo ? lo : v): max_pd(lo, v); std::min(v, hi) is min_pd(hi, v).
  v = _mm256_max_pd(_mm256_cvtps_pd(_mm_loadu_ps(lo)), v);
  v = _mm256_min_pd(_mm256_cvtps_pd(_mm_loadu_ps(hi)), v);
  const __m128 vf = _mm256_cvtpd_ps(v);
  if (run) {
    _mm_storeu_ps(next + c[0], vf);
  } else {
    alignas(16) float w[4];
    _mm_store_ps(w, vf);
    for (int l = 0; l < 4; ++l) next[c[l]] = w[l];
  }
  // zero_set_move: |v - f| where |f| < near and a face neighbour's sign differs.
  const __m256d zero = _mm256_setzero_pd();
  const __m256d neg = _mm256_cmp_pd(f, zero, _CMP_LT_OQ);
  __m256d across = _mm256_xor_pd(_mm256_cmp_pd(fxp, zero, _CMP_LT_OQ), neg);
  across = _mm256_or_pd(across, _mm256_xor_pd(_mm256_cmp_pd(fxm, zero, _CMP_LT_OQ), neg));
  across = _mm256_or_pd(across, _mm256_xor_pd(_mm256_cmp_pd(fyp, zero, _CMP_LT_OQ), neg));
  across = _mm256_or_pd(across, _mm256_xor_pd(_mm256_cmp_pd(fym, zero, _CMP_LT_OQ), neg));
  across = _mm256_or_pd(across, _mm256_xor_pd(_mm256_cmp_pd(fzp, zero, _CMP_LT_OQ), neg));
  across = _mm256_or_pd(across, _mm256_xor_pd(_mm256_cmp_pd(fzm, zero, _CMP_LT_OQ), neg));
  const __m256d sign = _mm256_set1_pd(-0.0);
  const __m256d close = _mm256_cmp_pd(_mm256_andnot_pd(sign, f), _mm256_set1_pd(near), _CMP_LT_OQ);
  const __m256d move = _mm256_and_pd(_mm256_and_pd(close, across), _mm256_andnot_pd(sign, _mm256_sub_pd(v, f)));
  alignas(32) double mv[4];
  _mm256_store_pd(mv, move);
  double m = 0;
  for (int l = 0; l < 4; ++l) m = std::max(m, mv[l]);
  return m;
}
#undef PM_AVX2
#endif

// One explicit step of level-set mean-curvature flow phi_t = kappa |grad phi|
// at the active nodes (Jacobi: reads `cur`, writes `next`, both working-box
// arrays that agree off the active nodes), clamped between the fillet and
// round distances lo[t], hi[t]. Returns the largest move of a node next to
// the zero set (a face neighbour across it) within `near` of it.
double flow_step(const Band& band, const std::vector<float>& cur, std::vector<float>& next,
                 const std::vector<float>& lo, const std::vector<float>& hi, const double h[3], double dt,
                 double near, bool avx2 = true) {
  const double ix = 1 / h[0], iy = 1 / h[1], iz = 1 / h[2];
  const std::size_t n = band.size();
  const std::size_t chunks = std::max<std::size_t>(1, n / 4096 + 1);
  std::vector<double> moved(chunks, 0.0);
  const std::ptrdiff_t* o = band.off;
  avx2 = avx2 && cpu_has_avx2();  // the AVX2 copy where asked for and available
  pm::parallel_for(std::size_t(0), chunks, [&](std::size_t ch) {
    const std::size_t b = n * ch / chunks, e = n * (ch + 1) / chunks;
    double m = 0;
    std::size_t t = b;
#if PM_AVX2_COPIES
    if (avx2)
      for (; t + 4 <= e; t += 4)
        m = std::max(m, flow_values_x4(cur.data(), next.data(), band.active.data() + t, o, ix, iy, iz, dt,
                                       lo.data() + t, hi.data() + t, near));
#endif
    for (; t < e; ++t) {
      const std::size_t c = band.active[t];
      const double v = flow_value(cur.data() + c, o, ix, iy, iz, dt, lo[t], hi[t]);
      next[c] = float(v);
      m = std::max(m, zero_set_move(cur.data() + c, o, v, near));
    }
    moved[ch] = m;
  });
  return *std::max_element(moved.begin(), moved.end());
}

// Whether active node t has a face neighbour across the zero set of v.
inline bool next_to_zero_set(const Band& band, const std::vector<float>& v, std::size_t t) {
  const float* r = v.data() + band.active[t];
  const bool neg = r[0] < 0;
  bool across = false;
  for (int k = 0; k < 6; ++k) across |= (r[band.off[k]] < 0) != neg;
  return across;
}

// Re-distance when |grad phi| at too many zero-set nodes leaves [1 - d, 1 + d]
// with d = kReinitDefect: when more than kReinitShare of them do. A node's
// central differences straddle the zero set, and where the surface bends on
// the scale of a voxel they are off by more than d whatever the field, so
// some nodes always are; a re-distancing keeps the values next to the zero
// set and cannot change theirs. Counting the share, not the worst node, keeps
// a flow whose field stays distance-like from re-distancing every cycle for
// them (frog5: 3-5% off after the first re-distancing and no better after
// five more; the background label then re-distanced 6 times instead of once,
// tighten 4.2 -> 3.0 s; interface rr means within 0.001, rr min 0.538 -> 0.504).
constexpr double kReinitDefect = 0.5;
constexpr double kReinitShare = 0.05;

// Share of the active nodes next to the zero set (a face neighbour across
// it) whose |grad phi| (central differences, world units) is off 1 by more
// than kReinitDefect; 0 when there are none.
double gradient_defect_share(const Band& band, const std::vector<float>& cur, const double h[3]) {
  const std::size_t n = band.size();
  const std::size_t chunks = std::max<std::size_t>(1, n / 4096 + 1);
  std::vector<std::size_t> zero(chunks, 0), off(chunks, 0);
  pm::parallel_for(std::size_t(0), chunks, [&](std::size_t ch) {
    for (std::size_t t = n * ch / chunks, e = n * (ch + 1) / chunks; t < e; ++t) {
      if (!next_to_zero_set(band, cur, t)) continue;
      const float* r = cur.data() + band.active[t];
      const std::ptrdiff_t* o = band.off;
      const double px = (double(r[o[0]]) - r[o[1]]) / (2 * h[0]);
      const double py = (double(r[o[2]]) - r[o[3]]) / (2 * h[1]);
      const double pz = (double(r[o[4]]) - r[o[5]]) / (2 * h[2]);
      ++zero[ch];
      off[ch] += std::fabs(std::sqrt(px * px + py * py + pz * pz) - 1) > kReinitDefect;
    }
  });
  std::size_t z = 0, b = 0;
  for (std::size_t ch = 0; ch < chunks; ++ch) {
    z += zero[ch];
    b += off[ch];
  }
  return z > 0 ? double(b) / double(z) : 0.0;
}

// Mean change of the active nodes next to the zero set (a face neighbour
// across it) from `before` (active node t's value at [t]) to `cur` (the
// working box), in units of h (0 when there are none).
double zero_set_mean_move(const Band& band, const std::vector<float>& cur, const std::vector<float>& before,
                          double h) {
  const std::size_t n = band.size();
  const std::size_t chunks = std::max<std::size_t>(1, n / 4096 + 1);
  std::vector<double> sum(chunks, 0.0), cnt(chunks, 0.0);
  pm::parallel_for(std::size_t(0), chunks, [&](std::size_t ch) {
    double s = 0, c = 0;
    for (std::size_t t = n * ch / chunks, e = n * (ch + 1) / chunks; t < e; ++t) {
      if (!next_to_zero_set(band, cur, t)) continue;
      s += std::fabs(double(cur[band.active[t]]) - double(before[t]));
      c += 1;
    }
    sum[ch] = s;
    cnt[ch] = c;
  });
  double s = 0, c = 0;
  for (std::size_t ch = 0; ch < chunks; ++ch) {  // in chunk order: the same sum for any thread count
    s += sum[ch];
    c += cnt[ch];
  }
  return c > 0 ? s / c / h : 0.0;
}

}  // namespace

namespace detail {
double tighten_flow_step(const std::vector<std::uint32_t>& active, const Dims& box, const std::vector<float>& cur,
                         std::vector<float>& next, const std::vector<float>& lo, const std::vector<float>& hi,
                         const double h[3], double dt, double near, bool avx2) {
  return flow_step(Band(active, box), cur, next, lo, hi, h, dt, near, avx2);
}
}  // namespace detail

std::string tighten_radius_note(const TightenResult& r) {
  std::ostringstream m;
  m << "tightening at radius " << r.requested_radius << " would erase it (thinner than 2 R everywhere); ";
  if (r.radius > 0)
    m << "tightened at radius " << r.radius << " instead";
  else
    m << "kept untightened (its voxels' own surface)";
  return m.str();
}

double tighten_outside_band_auto(const Geometry& g, int upsample) {
  const double d = std::sqrt(g.spacing(0) * g.spacing(0) + g.spacing(1) * g.spacing(1) + g.spacing(2) * g.spacing(2));
  return kTightenOutsideBandDiagonals * d / double(std::max(upsample, 1));
}

namespace {

// True when a node on the grid's faces lies outside (value > 0).
bool outside_reaches_faces(const std::vector<float>& f, const Dims& d) {
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j) {
      const bool face = k == 0 || k + 1 == d.nz || j == 0 || j + 1 == d.ny;
      const std::size_t step = face ? 1 : std::max<std::size_t>(d.nx - 1, 1);
      for (std::size_t i = 0; i < d.nx; i += step)
        if (f[i + d.nx * (j + d.ny * k)] > 0) return true;
    }
  return false;
}

}  // namespace

TightenResult tighten(const Volume& mask, const TightenParams& p) {
  if (!(p.radius > 0) || !std::isfinite(p.radius))
    throw UsageError("tighten: radius " + std::to_string(p.radius) + " is invalid; expected > 0 (world units)");
  if (p.upsample < 1 || p.upsample > 8)
    throw UsageError("tighten: upsample " + std::to_string(p.upsample) + " is invalid; expected 1 to 8");
  if (p.reinit_every < 1) throw UsageError("tighten: reinit_every must be >= 1");
  if (p.max_iterations < 0) throw UsageError("tighten: iterations must be >= 0 (0 = automatic)");
  if (!(p.tolerance > 0)) throw UsageError("tighten: tolerance must be > 0 (voxels)");

  TightenResult res;
  const std::vector<std::uint8_t> inside = binary_mask_inside(mask, "tighten: mask");
  const Dims& n0 = mask.dims();
  const Geometry& g0 = mask.geometry();
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b) {
      const Vec3 ca = g0.directions.column(a), cb = g0.directions.column(b);
      if (!(std::fabs(dot(ca, cb)) < 1e-6 * norm(ca) * norm(cb)))
        throw InputError("tighten: mask axes " + std::to_string(a) + " and " + std::to_string(b) +
                         " are not orthogonal; expected an orthogonal direction matrix");
    }
  const double r = p.radius;

  // Bounding box of the inside voxels and the padding the closing needs.
  std::size_t lo[3] = {n0.nx, n0.ny, n0.nz}, hi[3] = {0, 0, 0};
  for (std::size_t k = 0; k < n0.nz; ++k)
    for (std::size_t j = 0; j < n0.ny; ++j)
      for (std::size_t i = 0; i < n0.nx; ++i)
        if (inside[i + n0.nx * (j + n0.ny * k)]) {
          res.inside_voxels++;
          const std::size_t ijk[3] = {i, j, k};
          for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], ijk[a]);
            hi[a] = std::max(hi[a], ijk[a]);
          }
        }
  long pad = 0;
  for (int a = 0; a < 3; ++a) {
    const long margin = long(std::ceil(r / g0.spacing(a))) + 3;
    pad = std::max(pad, margin - long(lo[a]));
    pad = std::max(pad, long(hi[a]) + margin - (long(n0[a]) - 1));
  }
  if (p.pad >= 0) pad = p.pad;
  res.pad = std::size_t(std::max(0L, pad));
  const std::size_t P = res.pad;
  const Dims pd{n0.nx + 2 * P, n0.ny + 2 * P, n0.nz + 2 * P};
  Geometry gp = g0;
  gp.origin = g0.index_to_world(Vec3(-double(P), -double(P), -double(P)));

  // Fine grid (upsampling) and the grey field 0.5 - mask (negative inside).
  const std::size_t K = std::size_t(p.upsample);
  const Dims fd{(pd.nx - 1) * K + 1, (pd.ny - 1) * K + 1, (pd.nz - 1) * K + 1};
  if (double(fd.nx) * double(fd.ny) * double(fd.nz) >= double(std::numeric_limits<std::int32_t>::max())) {
    std::ostringstream m;
    m << "tighten: the " << (K > 1 ? "upsampled " : "") << "grid " << fd.nx << "x" << fd.ny << "x" << fd.nz
      << " exceeds 2^31 nodes; expected a smaller upsampling factor";
    throw InputError(m.str());
  }
  Geometry gf = gp;
  gf.directions = gp.directions * (1.0 / double(K));
  auto in_padded = [&](std::size_t i, std::size_t j, std::size_t k) -> double {
    if (i < P || j < P || k < P) return 0;
    i -= P;
    j -= P;
    k -= P;
    if (i >= n0.nx || j >= n0.ny || k >= n0.nz) return 0;
    return inside[i + n0.nx * (j + n0.ny * k)];
  };

  // Everything but the final re-distancing runs on a working box: the inside
  // voxels' bounding box plus r and the flowing band, in fine nodes.
  std::size_t wlo[3], whi[3];
  for (int a = 0; a < 3; ++a) {
    const std::size_t m = std::size_t(std::ceil(r / g0.spacing(a))) + 5;
    wlo[a] = (lo[a] + P > m ? lo[a] + P - m : 0) * K;
    whi[a] = std::min(hi[a] + P + m, pd[a] - 1) * K;
  }
  const Dims wd{whi[0] - wlo[0] + 1, whi[1] - wlo[1] + 1, whi[2] - wlo[2] + 1};
  Geometry gw = gf;
  gw.origin = gf.index_to_world(Vec3(double(wlo[0]), double(wlo[1]), double(wlo[2])));
  const std::size_t N = wd.count();
  std::vector<float> F(N);
  pm::parallel_for(std::size_t(0), wd.nz, [&](std::size_t kw) {
    const std::size_t k = kw + wlo[2];
    const std::size_t k0 = k / K, k1 = std::min(k0 + 1, pd.nz - 1);
    const double tz = double(k % K) / double(K);
    for (std::size_t jw = 0; jw < wd.ny; ++jw) {
      const std::size_t j = jw + wlo[1];
      const std::size_t j0 = j / K, j1 = std::min(j0 + 1, pd.ny - 1);
      const double ty = double(j % K) / double(K);
      for (std::size_t iw = 0; iw < wd.nx; ++iw) {
        const std::size_t i = iw + wlo[0];
        const std::size_t i0 = i / K, i1 = std::min(i0 + 1, pd.nx - 1);
        const double tx = double(i % K) / double(K);
        double m;
        if (K == 1) {
          m = in_padded(i, j, k);
        } else {
          const double c00 = in_padded(i0, j0, k0) * (1 - tx) + in_padded(i1, j0, k0) * tx;
          const double c10 = in_padded(i0, j1, k0) * (1 - tx) + in_padded(i1, j1, k0) * tx;
          const double c01 = in_padded(i0, j0, k1) * (1 - tx) + in_padded(i1, j0, k1) * tx;
          const double c11 = in_padded(i0, j1, k1) * (1 - tx) + in_padded(i1, j1, k1) * tx;
          m = (c00 * (1 - ty) + c10 * ty) * (1 - tz) + (c01 * (1 - ty) + c11 * ty) * tz;
        }
        F[iw + wd.nx * (jw + wd.ny * kw)] = float(0.5 - m);
      }
    }
  });

  const double h[3] = {gw.spacing(0), gw.spacing(1), gw.spacing(2)};
  const double hmin = std::min(h[0], std::min(h[1], h[2])), hmax = std::max(h[0], std::max(h[1], h[2]));
  // Half-width of the flowing band around the mortar: the curvature at a
  // node next to the zero set reads neighbours up to sqrt(2) voxels away, and
  // the ring beyond them only has to stay a sane level-set function. Two
  // voxels instead of three: a third fewer nodes and fewer steps to converge;
  // the zero set moves by < 0.07 voxel and its curvature bound is unchanged
  // (256^3 bench mask, r = 2).
  const double w = 2 * hmax;  // half-width of the flowing band around the mortar

  // Signed distances of S, the round (opening) and the fillet (closing).
  // Accurate values are needed near the levels -r and +r of dS (they define
  // the erosion and the dilation) and within w of the mortar.
  std::optional<ScopedStage> stage(std::in_place, "tighten.mortar");
  DistanceParams dp;
  dp.band = std::max(r, w) + hmax;
  auto timed_sd = [](const char* what, const std::vector<float>& f, const Dims& dd, const Geometry& gg,
                     const DistanceParams& q) {
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<float> out = signed_distance(f, dd, gg, q);
    add_seconds(what, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    return out;
  };
  std::vector<float> dS = timed_sd("tighten.sd_S", F, wd, gw, dp);
  std::vector<float>().swap(F);

  // A mask thinner than 2r everywhere (its depth, the largest distance of an
  // inside point to its surface, below r / 0.9) has an empty round: nothing holds
  // the flow and it shrinks the material to a dot. Never erase a material:
  // tighten at half the radius (same grid) until the round is not empty, and
  // below kTightenMinRadiusVoxels fine voxels keep the mask's own surface.
  // Dually, a complement thinner than 2r everywhere (a material filling the
  // box but for a small hole, e.g. the padding around a tiny volume) has a
  // full fillet and the flow would fill the hole.
  // (The complement counts only when it does not reach the working box's
  // faces: beyond them everything is outside, however large r.)
  // The result: `box` (the working box's field, released here) on the whole
  // grid, where every node outside the box is outside, re-distanced.
  auto redistance = [&](std::vector<float>& box) {
    stage.emplace("tighten.redistance");
    std::vector<float> full(fd.count(), FLT_MAX / 4);
    pm::parallel_for(std::size_t(0), wd.nz, [&](std::size_t kw) {
      for (std::size_t jw = 0; jw < wd.ny; ++jw)
        std::copy_n(box.begin() + long(wd.nx * (jw + wd.ny * kw)), wd.nx,
                    full.begin() + long(wlo[0] + fd.nx * (jw + wlo[1] + fd.ny * (kw + wlo[2]))));
    });
    std::vector<float>().swap(box);
    DistanceParams q;
    if (p.outside_band > 0 && outside_reaches_faces(full, fd)) {
      q.band = p.outside_band;
      q.band_outside_only = true;
    }
    const std::vector<float> d = signed_distance(full, fd, gf, q);
    res.distance = Volume(VoxelType::f32, fd, gf);
    float* out = res.distance.data<float>();
    const float sign = p.positive_inside ? -1.f : 1.f;
    for (std::size_t c = 0; c < d.size(); ++c) out[c] = sign * d[c];
    // Say so in the volume (NRRD keeps it): the tools that read farther out refuse it.
    if (q.band_outside_only) {
      char band[32];
      std::snprintf(band, sizeof band, "%.17g", q.band);  // the band itself, not a rounded-up value
      res.distance.set_key(p.positive_inside ? kExactNegativeKey : kExactPositiveKey, band);
    }
  };
  const auto [dmin, dmax] = std::minmax_element(dS.begin(), dS.end());
  const bool outside_on_faces = outside_reaches_faces(dS, wd);
  const double depth = std::min(-double(*dmin), outside_on_faces ? HUGE_VAL : double(*dmax));
  if (!(r <= kTightenRoundDepth * depth)) {
    if (r / 2 >= kTightenMinRadiusVoxels * hmin) {
      std::vector<float>().swap(dS);
      stage.reset();
      TightenParams q = p;
      q.radius = r / 2;
      q.pad = int(res.pad);
      TightenResult half = tighten(mask, q);
      half.pad = res.pad;
      half.requested_radius = p.radius;
      return half;
    }
    redistance(dS);
    res.converged = true;
    res.radius = 0;
    res.requested_radius = p.radius;
    return res;
  }
  dp.allow_no_crossing = true;  // the erosion can be empty (everything thinner than 2r)
  dp.band = w + hmax;
  dp.iso = -r;
  std::vector<float> dR = timed_sd("tighten.sd_round", dS, wd, gw, dp);
  dp.iso = r;
  std::vector<float> dF = timed_sd("tighten.sd_fillet", dS, wd, gw, dp);
  pm::parallel_for(std::size_t(0), N, [&](std::size_t c) {
    if (dR[c] < FLT_MAX) dR[c] = std::max(float(dR[c] - r), dS[c]);
    if (dF[c] > -FLT_MAX) dF[c] = std::min(float(dF[c] + r), dS[c]);
  });

  // Active nodes: where round and fillet differ near the mortar, off the border.
  std::vector<std::uint32_t> active;  // working-box indices (the box has < 2^31 nodes)
  {
    std::vector<std::vector<std::uint32_t>> per(wd.nz);
    pm::parallel_for(std::size_t(1), wd.nz - 1, [&](std::size_t k) {
      for (std::size_t j = 1; j + 1 < wd.ny; ++j)
        for (std::size_t i = 1; i + 1 < wd.nx; ++i) {
          const std::size_t c = i + wd.nx * (j + wd.ny * k);
          if (dF[c] < w && dR[c] > -w && double(dR[c]) - double(dF[c]) > 1e-4 * hmin)
            per[k].push_back(std::uint32_t(c));
        }
    });
    for (auto& v : per) active.insert(active.end(), v.begin(), v.end());
  }
  res.mortar_nodes = active.size();

  stage.emplace("tighten.flow");
  // Clamped mean-curvature flow on the working box. `phi` and `next` agree
  // off the active nodes, so a step writes `next` at the active nodes and
  // swaps the two.
  std::vector<float> lo_a(active.size()), hi_a(active.size());
  pm::parallel_for(std::size_t(0), active.size(), [&](std::size_t t) {
    lo_a[t] = dF[active[t]];
    hi_a[t] = dR[active[t]];
  });
  std::vector<float> phi = std::move(dS), next = phi;
  const Band band(active, wd);
  const double dt = 0.45 / (1 / (h[0] * h[0]) + 1 / (h[1] * h[1]) + 1 / (h[2] * h[2]));
  const int max_it = p.max_iterations > 0 ? p.max_iterations : int(20 * (r / hmin) * (r / hmin)) + 160;
  DistanceParams reinit;
  reinit.band = 2 * w;
  const std::size_t sy = wd.nx, sz = wd.nx * wd.ny;
  // The active values at the start of the current re-distancing cycle: a few
  // nodes on thin necks keep moving (the largest move rarely settles), while
  // the zero set as a whole converges geometrically; it has converged when
  // its mean move over a whole cycle is below kTightenCycleShare of the
  // tolerance.
  std::vector<float> cycle_start(active.size());
  auto take_cycle_start = [&] {
    pm::parallel_for(std::size_t(0), active.size(), [&](std::size_t t) { cycle_start[t] = phi[active[t]]; });
  };
  take_cycle_start();
  for (int it = 1; it <= max_it && !active.empty(); ++it) {
    check_cancelled();
    const double moved = flow_step(band, phi, next, lo_a, hi_a, h, dt, 1.5 * hmax);
    phi.swap(next);
    res.iterations = it;
    res.last_change = moved / hmin;
    const bool after_reinit = it > 1 && (it - 1) % p.reinit_every == 0;  // the first step relaxes the new field
    if (res.last_change < p.tolerance && !after_reinit) {
      res.converged = true;
      break;
    }
    if (it % p.reinit_every == 0) {
      res.cycle_change = zero_set_mean_move(band, phi, cycle_start, hmin);
      if (res.cycle_change < kTightenCycleShare * p.tolerance) {
        res.converged = true;
        break;
      }
      take_cycle_start();
    }
    // Re-distance only while the zero set still moves (near convergence it
    // would only perturb the flow) and only when the field has drifted from a
    // distance function at the zero set: the clamping to the round and fillet
    // distances keeps it close to one in most cases, and each re-distancing
    // costs a transform of the working box.
    if (it % p.reinit_every == 0 && res.last_change > 10 * p.tolerance &&
        gradient_defect_share(band, phi, h) > kReinitShare) {
      ++res.reinits;
      // Re-distance away from the zero set; nodes next to it keep their values
      // so the zero set does not move.
      const auto t0 = std::chrono::steady_clock::now();
      std::vector<float> d = signed_distance(phi, wd, gw, reinit);
      add_seconds("tighten.reinit", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      pm::parallel_for(std::size_t(1), wd.nz - 1, [&](std::size_t k) {
        for (std::size_t j = 1; j + 1 < wd.ny; ++j)
          for (std::size_t i = 1; i + 1 < wd.nx; ++i) {
            const std::size_t c = i + wd.nx * (j + wd.ny * k);
            const bool neg = phi[c] < 0;
            if ((phi[c + 1] < 0) != neg || (phi[c - 1] < 0) != neg || (phi[c + sy] < 0) != neg ||
                (phi[c - sy] < 0) != neg || (phi[c + sz] < 0) != neg || (phi[c - sz] < 0) != neg)
              d[c] = phi[c];
          }
      });
      phi.swap(d);
      for (std::size_t c : active) phi[c] = std::min(std::max(phi[c], dF[c]), dR[c]);
      std::copy(phi.begin(), phi.end(), next.begin());
    }
  }
  if (active.empty()) res.converged = true;
  res.radius = r;
  res.requested_radius = p.radius;

  std::vector<float>().swap(next);
  redistance(phi);
  if (p.keep_mortar) {
    res.round = Volume(VoxelType::f32, fd, gf);
    res.fillet = Volume(VoxelType::f32, fd, gf);
    float* R = res.round.data<float>();
    float* Fi = res.fillet.data<float>();
    std::fill(R, R + fd.count(), FLT_MAX);
    std::fill(Fi, Fi + fd.count(), FLT_MAX);
    for (std::size_t kw = 0; kw < wd.nz; ++kw)
      for (std::size_t jw = 0; jw < wd.ny; ++jw)
        for (std::size_t iw = 0; iw < wd.nx; ++iw) {
          const std::size_t c = iw + wlo[0] + fd.nx * (jw + wlo[1] + fd.ny * (kw + wlo[2]));
          R[c] = dR[iw + wd.nx * (jw + wd.ny * kw)];
          Fi[c] = dF[iw + wd.nx * (jw + wd.ny * kw)];
        }
  }
  return res;
}

void tighten_labels(const Volume& lv, const TightenParams& p,
                    const std::function<void(int, TightenResult&&)>& sink) {
  if (!(p.radius > 0))
    throw UsageError("tighten: radius " + std::to_string(p.radius) + " is invalid; expected > 0 (world units)");
  if (p.upsample < 1 || p.upsample > 8)
    throw UsageError("tighten: upsample " + std::to_string(p.upsample) + " is invalid; expected 1 to 8");
  const Dims& n0 = lv.dims();
  std::vector<int> lab(lv.count());
  std::map<int, std::size_t> counts;
  // int32 label maps read directly; the counts go to the map once per run of
  // equal labels.
  const std::int32_t* i32 = lv.type() == VoxelType::i32 ? lv.data<std::int32_t>() : nullptr;
  int run_label = 0;
  std::size_t run = 0;
  for (std::size_t c = 0; c < lv.count(); ++c) {
    const double v = i32 ? double(i32[c]) : lv.get(c);
    if (!std::isfinite(v) || v != std::floor(v) || std::fabs(v) > 2147483647.0) {
      std::ostringstream m;
      m << "tighten: voxel (" << c % n0.nx << "," << (c / n0.nx) % n0.ny << "," << c / (n0.nx * n0.ny) << ") is "
        << v << "; expected a label map with integer values";
      throw InputError(m.str());
    }
    lab[c] = int(v);
    if (run > 0 && lab[c] == run_label) {
      ++run;
    } else {
      if (run > 0) counts[run_label] += run;
      run_label = lab[c];
      run = 1;
    }
  }
  if (run > 0) counts[run_label] += run;
  if (counts.size() < 2)
    throw InputError("tighten: the label map has only one label (" + std::to_string(counts.begin()->first) +
                     "); expected at least 2 materials");
  const Geometry& g0 = lv.geometry();
  long P = 0;
  for (int a = 0; a < 3; ++a) P = std::max(P, long(std::ceil(p.radius / g0.spacing(a))) + 3);
  const Dims pd{n0.nx + 2 * P, n0.ny + 2 * P, n0.nz + 2 * P};
  Geometry gp = g0;
  gp.origin = g0.index_to_world(Vec3(-double(P), -double(P), -double(P)));
  auto clampi = [](long i, std::size_t n) { return std::size_t(std::min(std::max(i, 0L), long(n) - 1)); };
  std::vector<int> padded(pd.count());
  for (std::size_t k = 0; k < pd.nz; ++k)
    for (std::size_t j = 0; j < pd.ny; ++j)
      for (std::size_t i = 0; i < pd.nx; ++i)
        padded[i + pd.nx * (j + pd.ny * k)] =
            lab[clampi(long(i) - P, n0.nx) + n0.nx * (clampi(long(j) - P, n0.ny) + n0.ny * clampi(long(k) - P, n0.nz))];
  std::vector<int>().swap(lab);
  TightenParams q = p;
  q.pad = 0;
  const std::size_t K = std::size_t(p.upsample), off = std::size_t(P) * K;
  const Dims od{(n0.nx - 1) * K + 1, (n0.ny - 1) * K + 1, (n0.nz - 1) * K + 1};
  Geometry go = g0;
  go.directions = g0.directions * (1.0 / double(K));
  // Labels are tightened side by side, one per thread (each label's own
  // loops share the threads that are free), and handed to the sink in label
  // order: a result waits until every smaller label has been handed on. The
  // results are those of one label at a time; the first failing label in
  // label order is the one reported, after the labels before it.
  std::vector<int> order;
  for (const auto& kv : counts) order.push_back(kv.first);
  const std::size_t nl = order.size();
  std::vector<std::optional<TightenResult>> done(nl);
  std::vector<std::exception_ptr> failed(nl);
  std::mutex emit_mutex;
  std::size_t next_emit = 0;
  bool stop = false;
  std::exception_ptr sink_error;
  auto crop = [&](const Volume& full) {  // the padded, upsampled grid back to the label map's extent
    if (full.empty()) return Volume();
    const Dims& fd = full.dims();
    Volume o(VoxelType::f32, od, go);
    const float* src = full.data<float>();
    float* dst = o.data<float>();
    for (std::size_t k = 0; k < od.nz; ++k)
      for (std::size_t j = 0; j < od.ny; ++j)
        for (std::size_t i = 0; i < od.nx; ++i)
          dst[i + od.nx * (j + od.ny * k)] = src[(i + off) + fd.nx * ((j + off) + fd.ny * (k + off))];
    for (const auto& [key, value] : full.keys()) o.set_key(key, value);  // the same values: the same band
    return o;
  };
  auto one_label = [&](std::size_t li) {
    const int label = order[li];
    try {
      Volume mask(VoxelType::u8, pd, gp);
      std::uint8_t* m = mask.data<std::uint8_t>();
      for (std::size_t c = 0; c < padded.size(); ++c) m[c] = padded[c] == label ? 1 : 0;
      TightenResult r;
      try {
        r = tighten(mask, q);
      } catch (const InputError& e) {
        throw InputError("label " + std::to_string(label) + ": " + e.what());
      }
      r.distance = crop(r.distance);
      if (p.keep_mortar) {
        r.round = crop(r.round);
        r.fillet = crop(r.fillet);
      }
      const std::lock_guard<std::mutex> lock(emit_mutex);
      done[li] = std::move(r);
    } catch (...) {
      const std::lock_guard<std::mutex> lock(emit_mutex);
      failed[li] = std::current_exception();
    }
    const std::lock_guard<std::mutex> lock(emit_mutex);
    while (!stop && next_emit < nl && (done[next_emit] || failed[next_emit])) {
      if (failed[next_emit]) {
        stop = true;
        break;
      }
      try {
        sink(order[next_emit], std::move(*done[next_emit]));
      } catch (...) {
        sink_error = std::current_exception();
        stop = true;
        break;
      }
      done[next_emit].reset();
      ++next_emit;
    }
  };
  // Each label in flight holds its own grids (about kTightenBytesPerVoxel per
  // padded, upsampled voxel at its peak, the final re-distancing): labels go
  // side by side only while the extra ones fit in kTightenSideBySideBytes
  // (frog5, 4.3M voxels: two at a time, 4.6 -> 4.1 s, peak 220 -> 460 MB; the
  // full-resolution frog one at a time).
  const double label_bytes = kTightenBytesPerVoxel * double((pd.nx - 1) * K + 1) * double((pd.ny - 1) * K + 1) *
                             double((pd.nz - 1) * K + 1);
  const std::size_t extra = std::size_t(kTightenSideBySideBytes / std::max(label_bytes, 1.0));
  const std::size_t workers = std::min<std::size_t>(
      {nl, std::size_t(std::max(1, tbb::this_task_arena::max_concurrency())), 1 + extra});
  std::atomic<std::size_t> next_label{0};
  pm::parallel_for(std::size_t(0), workers, [&](std::size_t) {
    for (std::size_t li; (li = next_label.fetch_add(1)) < nl;) {
      {
        const std::lock_guard<std::mutex> lock(emit_mutex);
        if (stop) return;
      }
      tbb::this_task_arena::isolate([&] { one_label(li); });
    }
  });
  if (sink_error) std::rethrow_exception(sink_error);
  for (std::size_t li = 0; li < nl; ++li)
    if (failed[li]) std::rethrow_exception(failed[li]);
}

}  // namespace pm
