#include "pm/field/distance.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "pm/base/cpu.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif
#if PM_AVX2_COPIES
#include <immintrin.h>
#endif

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>

#include "pm/base/error.h"
#include "pm/base/parallel.h"

namespace pm {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Line {
  std::vector<double> f, z, g;
  std::vector<std::int32_t> site, v;
  std::vector<float> out_f;
  std::vector<std::int32_t> out_site;
  void resize(std::size_t n) {
    f.resize(n);
    z.resize(n + 1);
    g.resize(n);
    site.resize(n);
    v.resize(n);
    out_f.resize(n);
    out_site.resize(n);
  }
};

// Lower envelope of parabolas (Felzenszwalb & Huttenlocher 2012) along one
// line of n samples with spacing h: out_f[x] = min_q f[q] + (h (x - q))², and
// out_site[x] = site[q] of the minimising q. Infinite f[q] are not sites.
void envelope_1d(Line& L, std::size_t n, double h) {
  const double hh = h * h;
  int k = -1;
  // g[k]: f[p] + hh p² of the parabola v[k] = p, kept from when it was
  // pushed (the same double as recomputing it).
  for (std::size_t q = 0; q < n; ++q) {
    if (!(L.f[q] < kInf)) continue;
    const double fq = L.f[q] + hh * double(q) * double(q);
    double s = -kInf;
    while (k >= 0) {
      const std::size_t p = std::size_t(L.v[std::size_t(k)]);
      s = (fq - L.g[std::size_t(k)]) / (2.0 * hh * (double(q) - double(p)));
      if (s <= L.z[std::size_t(k)]) --k;
      else break;
    }
    ++k;
    L.v[std::size_t(k)] = std::int32_t(q);
    L.g[std::size_t(k)] = fq;
    L.z[std::size_t(k)] = k == 0 ? -kInf : s;
    L.z[std::size_t(k) + 1] = kInf;
  }
  if (k < 0) {
    std::fill(L.out_f.begin(), L.out_f.begin() + long(n), std::numeric_limits<float>::infinity());
    std::fill(L.out_site.begin(), L.out_site.begin() + long(n), -1);
    return;
  }
  std::size_t j = 0;
  for (std::size_t x = 0; x < n; ++x) {
    while (L.z[j + 1] < double(x)) ++j;
    const std::size_t q = std::size_t(L.v[j]);
    const double dx = h * (double(x) - double(q));
    L.out_f[x] = float(L.f[q] + dx * dx);
    L.out_site[x] = L.site[q];
  }
}

// envelope_1d for the first pass, whose values are 0 at the sites (band[i]
// >= 0) and infinite elsewhere, straight into the outputs: the parabolas of
// consecutive sites p < q meet at s, computed as envelope_1d computes it,
// and node x takes q when s < x, as there (no parabola of such a row is ever
// popped). The same floats and sites as envelope_1d.
void envelope_sites(const std::int32_t* band, std::size_t n, double h, std::size_t base, float* out_f,
                    std::int32_t* out_site) {
  const double hh = h * h;
  std::size_t p = 0;
  while (p < n && band[p] < 0) ++p;
  if (p == n) {
    std::fill(out_f, out_f + n, std::numeric_limits<float>::infinity());
    std::fill(out_site, out_site + n, -1);
    return;
  }
  auto put = [&](std::size_t x, std::size_t q) {
    const double dx = h * (double(x) - double(q));
    out_f[x] = float(0.0 + dx * dx);
    out_site[x] = std::int32_t(base + q);
  };
  std::size_t x = 0;
  for (; x < p; ++x) put(x, p);
  for (;;) {
    std::size_t q = p + 1;
    while (q < n && band[q] < 0) ++q;
    if (q == n) {
      for (; x < n; ++x) put(x, p);
      return;
    }
    const double fq = 0.0 + hh * double(q) * double(q);
    const double sp = (fq - (0.0 + hh * double(p) * double(p))) / (2.0 * hh * (double(q) - double(p)));
    for (; x < q; ++x) put(x, sp < double(x) ? q : p);
    p = q;
  }
}

void check_orthogonal(const Geometry& g, const char* who) {
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b) {
      const Vec3 ca = g.directions.column(a), cb = g.directions.column(b);
      const double c = std::fabs(dot(ca, cb)) / (norm(ca) * norm(cb));
      if (!(c < 1e-6)) {
        std::ostringstream m;
        m << who << ": axes " << a << " and " << b << " are not orthogonal (cos = " << c
          << "); expected an orthogonal direction matrix";
        throw InputError(m.str());
      }
    }
  for (int a = 0; a < 3; ++a)
    if (!(g.spacing(a) > 0) || !std::isfinite(g.spacing(a)))
      throw InputError(std::string(who) + ": axis " + std::to_string(a) + " has zero or non-finite spacing");
}

}  // namespace

namespace {

// Squared distances from x to the discs (p, m) of candidates 0 .. n-1, four
// at a time with SSE2 (baseline x86-64). The same IEEE operations in the same
// order as the scalar formula of disc_d2_below (without its early exit), so
// the same floats: v = float(p - x) in double, |v|², the normal part a², the
// lateral part beyond the disc's radius rho; a disc without a normal (m = 0)
// is a point. Slots n .. up to the next multiple of four are computed too
// (from whatever they hold) and ignored by the caller.
constexpr int kCandSlots = detail::kDiscSlots;  // 27 candidates, rounded up to a multiple of 8

void disc_d2_x4(const float (&p)[3][kCandSlots], const float (&m)[3][kCandSlots], int n, const double x[3],
                float rho, float (&out)[kCandSlots]) {
#if !defined(__SSE2__)
  for (int q = 0; q < n; ++q) {  // the same formula, one disc at a time
    const float v0 = float(double(p[0][q]) - x[0]), v1 = float(double(p[1][q]) - x[1]),
                v2 = float(double(p[2][q]) - x[2]);
    const float vv = v0 * v0 + v1 * v1 + v2 * v2;
    const float a = v0 * m[0][q] + v1 * m[1][q] + v2 * m[2][q];
    const float aa = a * a;
    const float lat2 = std::max(0.f, vv - aa);
    const float lat = std::sqrt(lat2) - rho;
    const bool point = m[0][q] == 0 && m[1][q] == 0 && m[2][q] == 0;
    out[q] = point ? vv : lat2 <= rho * rho ? aa : aa + lat * lat;
  }
#else
  const __m128d x0 = _mm_set1_pd(x[0]), x1 = _mm_set1_pd(x[1]), x2 = _mm_set1_pd(x[2]);
  const __m128 zero = _mm_setzero_ps(), r = _mm_set1_ps(rho), r2 = _mm_set1_ps(rho * rho);
  auto sub = [](const float* v, __m128d c) {  // float(double(v[i]) - c) for four v
    const __m128 lo = _mm_cvtpd_ps(_mm_sub_pd(_mm_cvtps_pd(_mm_loadl_pi(_mm_setzero_ps(), (const __m64*)v)), c));
    const __m128 hi =
        _mm_cvtpd_ps(_mm_sub_pd(_mm_cvtps_pd(_mm_loadl_pi(_mm_setzero_ps(), (const __m64*)(v + 2))), c));
    return _mm_movelh_ps(lo, hi);
  };
  for (int q = 0; q < n; q += 4) {
    const __m128 v0 = sub(p[0] + q, x0), v1 = sub(p[1] + q, x1), v2 = sub(p[2] + q, x2);
    const __m128 m0 = _mm_load_ps(m[0] + q), m1 = _mm_load_ps(m[1] + q), m2 = _mm_load_ps(m[2] + q);
    const __m128 vv = _mm_add_ps(_mm_add_ps(_mm_mul_ps(v0, v0), _mm_mul_ps(v1, v1)), _mm_mul_ps(v2, v2));
    const __m128 a = _mm_add_ps(_mm_add_ps(_mm_mul_ps(v0, m0), _mm_mul_ps(v1, m1)), _mm_mul_ps(v2, m2));
    const __m128 aa = _mm_mul_ps(a, a);
    const __m128 lat2 = _mm_max_ps(_mm_sub_ps(vv, aa), zero);  // (vv - aa > 0) ? vv - aa : +0, as std::max(0.f, .)
    const __m128 lat = _mm_sub_ps(_mm_sqrt_ps(lat2), r);
    const __m128 in = _mm_cmple_ps(lat2, r2);
    const __m128 d2 = _mm_or_ps(_mm_and_ps(in, aa), _mm_andnot_ps(in, _mm_add_ps(aa, _mm_mul_ps(lat, lat))));
    const __m128 point =
        _mm_and_ps(_mm_and_ps(_mm_cmpeq_ps(m0, zero), _mm_cmpeq_ps(m1, zero)), _mm_cmpeq_ps(m2, zero));
    _mm_store_ps(out + q, _mm_or_ps(_mm_and_ps(point, vv), _mm_andnot_ps(point, d2)));
  }
#endif
}

#if PM_AVX2_COPIES
// float(double(v[i]) - c) for eight v.
__attribute__((target("avx2"))) inline __m256 sub_x8(const float* v, __m256d c) {
  const __m128 lo = _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_cvtps_pd(_mm_load_ps(v)), c));
  const __m128 hi = _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_cvtps_pd(_mm_load_ps(v + 4)), c));
  return _mm256_insertf128_ps(_mm256_castps128_ps256(lo), hi, 1);
}

// disc_d2_x4 eight at a time (AVX2, chosen at run time): the same IEEE
// operations in the same order on every lane (no FMA), so the same floats;
// slots n .. up to the next multiple of eight are computed and ignored.
__attribute__((target("avx2"))) void disc_d2_x8(const float (&p)[3][kCandSlots], const float (&m)[3][kCandSlots],
                                                int n, const double x[3], float rho, float (&out)[kCandSlots]) {
  const __m256d x0 = _mm256_set1_pd(x[0]), x1 = _mm256_set1_pd(x[1]), x2 = _mm256_set1_pd(x[2]);
  const __m256 zero = _mm256_setzero_ps(), r = _mm256_set1_ps(rho), r2 = _mm256_set1_ps(rho * rho);
  for (int q = 0; q < n; q += 8) {
    const __m256 v0 = sub_x8(p[0] + q, x0), v1 = sub_x8(p[1] + q, x1), v2 = sub_x8(p[2] + q, x2);
    const __m256 m0 = _mm256_load_ps(m[0] + q), m1 = _mm256_load_ps(m[1] + q), m2 = _mm256_load_ps(m[2] + q);
    const __m256 vv =
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(v0, v0), _mm256_mul_ps(v1, v1)), _mm256_mul_ps(v2, v2));
    const __m256 a =
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(v0, m0), _mm256_mul_ps(v1, m1)), _mm256_mul_ps(v2, m2));
    const __m256 aa = _mm256_mul_ps(a, a);
    const __m256 lat2 = _mm256_max_ps(_mm256_sub_ps(vv, aa), zero);
    const __m256 lat = _mm256_sub_ps(_mm256_sqrt_ps(lat2), r);
    const __m256 in = _mm256_cmp_ps(lat2, r2, _CMP_LE_OQ);
    const __m256 d2 = _mm256_blendv_ps(_mm256_add_ps(aa, _mm256_mul_ps(lat, lat)), aa, in);
    const __m256 point = _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(m0, zero, _CMP_EQ_OQ),
                                                     _mm256_cmp_ps(m1, zero, _CMP_EQ_OQ)),
                                       _mm256_cmp_ps(m2, zero, _CMP_EQ_OQ));
    _mm256_store_ps(out + q, _mm256_blendv_ps(d2, vv, point));
  }
}

// The first strict minimum of d[0 .. n) (the scalar search's: starting from
// +infinity, the first d[q] < best wins, NaN never), eight lanes at a time:
// the smallest value by a min-reduction (NaN and the slots from n on count
// as +infinity), then the first slot holding it. Returns its index, or -1
// when no d[q] is below +infinity (best is then +infinity).
__attribute__((target("avx2"))) int first_min_x8(const float (&d)[kCandSlots], int n, float& best) {
  const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  __m256 m = inf;
  for (int q = 0; q < n; q += 8) {
    const __m256 v = _mm256_load_ps(d + q);
    const __m256 valid = _mm256_and_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(n - q), lane)),
                                       _mm256_cmp_ps(v, v, _CMP_ORD_Q));
    m = _mm256_min_ps(m, _mm256_blendv_ps(inf, v, valid));
  }
  __m128 t = _mm_min_ps(_mm256_castps256_ps128(m), _mm256_extractf128_ps(m, 1));
  t = _mm_min_ps(t, _mm_movehl_ps(t, t));
  t = _mm_min_ss(t, _mm_shuffle_ps(t, t, 1));
  best = _mm_cvtss_f32(t);
  if (!(best < std::numeric_limits<float>::infinity())) return -1;
  const __m256 b = _mm256_set1_ps(best);
  for (int q = 0; q < n; q += 8) {
    const int valid = n - q >= 8 ? 0xFF : (1 << (n - q)) - 1;
    const int hit = _mm256_movemask_ps(_mm256_cmp_ps(_mm256_load_ps(d + q), b, _CMP_EQ_OQ)) & valid;
    if (hit) return q + __builtin_ctz(unsigned(hit));
  }
  return -1;
}
#endif

// The candidate search's two kernels, the AVX2 copies where `avx2` (the
// caller has checked the CPU) and the baseline ones elsewhere.
void candidate_distances(const float (&p)[3][kCandSlots], const float (&m)[3][kCandSlots], int n,
                         const double x[3], float rho, float (&out)[kCandSlots], bool avx2) {
#if PM_AVX2_COPIES
  if (avx2) return disc_d2_x8(p, m, n, x, rho, out);
#endif
  (void)avx2;
  disc_d2_x4(p, m, n, x, rho, out);
}

int first_minimum(const float (&d)[kCandSlots], int n, float& best, bool avx2) {
#if PM_AVX2_COPIES
  if (avx2) return first_min_x8(d, n, best);
#endif
  (void)avx2;
  best = std::numeric_limits<float>::infinity();
  int arg = -1;
  for (int q = 0; q < n; ++q) {  // without a branch
    const bool lt = d[q] < best;
    best = lt ? d[q] : best;
    arg = lt ? q : arg;
  }
  return arg;
}

}  // namespace

namespace detail {

void disc_distances(const float (&p)[3][kDiscSlots], const float (&m)[3][kDiscSlots], int n, const double x[3],
                    float rho, float (&out)[kDiscSlots], bool avx2) {
  candidate_distances(p, m, n, x, rho, out, avx2 && cpu_has_avx2());
}

int first_strict_minimum(const float (&d)[kDiscSlots], int n, float& best, bool avx2) {
  return first_minimum(d, n, best, avx2 && cpu_has_avx2());
}

}  // namespace detail

std::vector<float> signed_distance(const std::vector<float>& f, const Dims& dims, const Geometry& g,
                                   const DistanceParams& p) {
  const char* who = "signed_distance";
  if (f.size() != dims.count())
    throw InputError(std::string(who) + ": " + std::to_string(f.size()) + " values for a grid of " +
                     std::to_string(dims.count()) + " nodes");
  check_orthogonal(g, who);
  if (dims.count() >= std::size_t(std::numeric_limits<std::int32_t>::max()))
    throw InputError(std::string(who) + ": grid too large (" + std::to_string(dims.count()) +
                     " nodes); expected < 2^31");
  const std::size_t nx = dims.nx, ny = dims.ny, nz = dims.nz, nxy = nx * ny, n = dims.count();
  const double h[3] = {g.spacing(0), g.spacing(1), g.spacing(2)};
  const std::size_t stride[3] = {1, nx, nxy};
  const double iso = p.iso;
  auto below = [&](std::size_t i) { return double(f[i]) < iso; };

  // 1. Band nodes (a face neighbour on the other side) and their foot points,
  //    as offsets in the scaled-index frame (axis a in world units h[a]).
  std::vector<std::int32_t> band(n, -1);
  std::vector<std::size_t> per_slice(nz + 1, 0);
  // below() of every node as a byte, then a node is a band node when it lies
  // on the level set or a face neighbour's byte differs from its own.
  std::vector<std::uint8_t> bl(n);
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    for (std::size_t c = nxy * k, e = c + nxy; c < e; ++c) bl[c] = below(c) ? 1 : 0;
  });
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    std::size_t cnt = 0;
    for (std::size_t j = 0; j < ny; ++j) {
      const std::size_t row = nx * j + nxy * k;
      const std::uint8_t* r = bl.data() + row;
      const std::uint8_t* ym = j > 0 ? r - nx : nullptr;
      const std::uint8_t* yp = j + 1 < ny ? r + nx : nullptr;
      const std::uint8_t* zm = k > 0 ? r - nxy : nullptr;
      const std::uint8_t* zp = k + 1 < nz ? r + nxy : nullptr;
      for (std::size_t i = 0; i < nx; ++i) {
        const std::uint8_t b = r[i];
        bool on = double(f[row + i]) == iso;
        on |= i > 0 && r[i - 1] != b;
        on |= i + 1 < nx && r[i + 1] != b;
        on |= ym && ym[i] != b;
        on |= yp && yp[i] != b;
        on |= zm && zm[i] != b;
        on |= zp && zp[i] != b;
        if (on) {
          band[row + i] = 0;
          ++cnt;
        }
      }
    }
    per_slice[k + 1] = cnt;
  });
  std::vector<std::uint8_t>().swap(bl);
  for (std::size_t k = 0; k < nz; ++k) per_slice[k + 1] += per_slice[k];
  const std::size_t nband = per_slice[nz];
  if (nband == 0) {
    if (!p.allow_no_crossing) {
      float lo = f[0], hi = f[0];
      for (float v : f) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
      std::ostringstream m;
      m << who << ": no voxels straddle the isovalue " << iso << " (values range from " << lo << " to " << hi
        << "); expected a level set inside the volume";
      throw InputError(m.str());
    }
    std::vector<float> out(n);
    for (std::size_t c = 0; c < n; ++c) out[c] = below(c) ? -FLT_MAX : FLT_MAX;
    return out;
  }
  std::vector<std::array<float, 3>> foot(nband);
  std::vector<std::array<float, 3>> normal(nband, {0.f, 0.f, 0.f});  // unit, or 0: a point
  std::vector<std::size_t> bnode(nband);
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    std::int32_t id = std::int32_t(per_slice[k]);
    for (std::size_t j = 0; j < ny; ++j)
      for (std::size_t i = 0; i < nx; ++i) {
        const std::size_t c = i + nx * j + nxy * k;
        if (band[c] < 0) continue;
        band[c] = id;
        bnode[std::size_t(id)] = c;
        std::array<float, 3>& off = foot[std::size_t(id)];
        off = {0.f, 0.f, 0.f};
        ++id;
        const double fc = double(f[c]) - iso;
        if (fc == 0) continue;
        const bool b = fc < 0;
        const std::size_t ijk[3] = {i, j, k};
        double cross[3] = {kInf, kInf, kInf}, inv[3] = {0, 0, 0}, sum = 0, nearest = kInf;
        for (int a = 0; a < 3; ++a) {
          for (int s = -1; s <= 1; s += 2) {
            if (s < 0 && ijk[a] == 0) continue;
            if (s > 0 && ijk[a] + 1 >= dims[a]) continue;
            const std::size_t o = s < 0 ? c - stride[a] : c + stride[a];
            const double fo = double(f[o]) - iso;
            if ((fo < 0) == b && fo != 0) continue;
            const double t = fc / (fc - fo);  // in (0, 1]
            if (t * h[a] < std::fabs(cross[a])) cross[a] = s * t * h[a];
          }
          if (cross[a] == kInf) continue;
          nearest = std::min(nearest, std::fabs(cross[a]));
          if (cross[a] != 0) {
            inv[a] = 1.0 / cross[a];
            sum += inv[a] * inv[a];
          }
        }
        if (nearest == 0 || sum == 0) continue;
        // Preferred: the plane through the crossing on the axis best aligned
        // with the central-difference gradient, normal to that gradient (exact
        // for linear fields). Fallback when the gradient is degenerate or
        // nearly tangent to every crossing axis (e.g. a one-voxel mask): the
        // plane through the axis intercepts.
        double gr[3];
        for (int a = 0; a < 3; ++a) {
          const std::size_t lo = ijk[a] > 0 ? c - stride[a] : c;
          const std::size_t hi = ijk[a] + 1 < dims[a] ? c + stride[a] : c;
          const double span = double((ijk[a] > 0) + (ijk[a] + 1 < dims[a])) * h[a];
          gr[a] = span > 0 ? (double(f[hi]) - double(f[lo])) / span : 0.0;
        }
        const double gn = std::sqrt(gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2]);
        int best_axis = -1;
        double best_cos = 0.1;
        if (gn > 0)
          for (int a = 0; a < 3; ++a)
            if (cross[a] != kInf && std::fabs(gr[a]) / gn > best_cos) {
              best_cos = std::fabs(gr[a]) / gn;
              best_axis = a;
            }
        std::array<float, 3>& nrm = normal[std::size_t(band[c])];
        if (best_axis >= 0) {
          const double sd = gr[best_axis] / gn * cross[best_axis];  // distance to that plane
          const double len = std::min(std::fabs(sd), nearest) * (sd < 0 ? -1 : 1);
          for (int a = 0; a < 3; ++a) {
            off[std::size_t(a)] = float(len * gr[a] / gn);
            nrm[std::size_t(a)] = float(gr[a] / gn);
          }
        } else {
          const double in = 1.0 / std::sqrt(sum);
          for (int a = 0; a < 3; ++a) {
            off[std::size_t(a)] = float(inv[a] / sum);
            // A gradient that disagrees with every crossing axis makes the
            // intercept plane suspect: keep the foot point as a point.
            nrm[std::size_t(a)] = gn > 0 ? 0.f : float(inv[a] * in);
          }
        }
      }
  });

  // 2. Exact squared EDT to the band nodes, carrying the nearest node index.
  std::vector<float> sq(n);
  std::vector<std::int32_t> site(n);
  const std::size_t counts[3] = {nx, ny, nz};
  // Lines along x and y, slice by slice (a slice is contiguous).
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, nz), [&](const tbb::blocked_range<std::size_t>& r) {
    Line L;
    L.resize(std::max(nx, ny));
    for (std::size_t k = r.begin(); k != r.end(); ++k) {
      for (std::size_t j = 0; j < ny; ++j) {
        const std::size_t base = nx * j + nxy * k;
        envelope_sites(band.data() + base, nx, h[0], base, sq.data() + base, site.data() + base);
      }
      for (std::size_t i = 0; i < nx; ++i) {
        const std::size_t base = i + nxy * k;
        for (std::size_t j = 0; j < ny; ++j) {
          L.f[j] = double(sq[base + nx * j]);
          L.site[j] = site[base + nx * j];
        }
        envelope_1d(L, ny, h[1]);
        for (std::size_t j = 0; j < ny; ++j) {
          sq[base + nx * j] = L.out_f[j];
          site[base + nx * j] = L.out_site[j];
        }
      }
    }
  });
  // Lines along z, in blocks of kBlock neighbouring lines so every gather and
  // scatter touches whole cache lines.
  constexpr std::size_t kBlock = 16;
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, ny), [&](const tbb::blocked_range<std::size_t>& r) {
    std::vector<Line> lines(kBlock);
    for (Line& L : lines) L.resize(nz);
    for (std::size_t j = r.begin(); j != r.end(); ++j)
      for (std::size_t i0 = 0; i0 < nx; i0 += kBlock) {
        const std::size_t nb = std::min(kBlock, nx - i0);
        for (std::size_t k = 0; k < nz; ++k) {
          const std::size_t base = i0 + nx * j + nxy * k;
          for (std::size_t b = 0; b < nb; ++b) {
            lines[b].f[k] = double(sq[base + b]);
            lines[b].site[k] = site[base + b];
          }
        }
        for (std::size_t b = 0; b < nb; ++b) envelope_1d(lines[b], nz, h[2]);
        for (std::size_t k = 0; k < nz; ++k) {
          const std::size_t base = i0 + nx * j + nxy * k;
          for (std::size_t b = 0; b < nb; ++b) {
            sq[base + b] = lines[b].out_f[k];
            site[base + b] = lines[b].out_site[k];
          }
        }
      }
  });

  // 3. Each band node stands for a small tangent disc of radius rho at its
  //    foot point (normal from the gradient; a plain point when the normal is
  //    unknown). Candidate for every node: the nearest disc among those of its
  //    nearest band node and that node's 26 neighbours. From here on `site`
  //    holds a band id and `sq` the squared distance to its disc.
  struct Disc {
    float p[3], m[3];
    bool below;  // the band node's side of the level set
  };
  std::vector<Disc> disc(nband);
  pm::parallel_for(std::size_t(0), nband, [&](std::size_t b) {
    const std::size_t q = bnode[b];
    const double qi[3] = {double(q % nx), double((q / nx) % ny), double(q / nxy)};
    for (int a = 0; a < 3; ++a) {
      disc[b].p[a] = float(qi[a] * h[a] + double(foot[b][std::size_t(a)]));
      disc[b].m[a] = normal[b][std::size_t(a)];
    }
    disc[b].below = below(q);
  });
  std::vector<std::array<float, 3>>().swap(foot);
  std::vector<std::array<float, 3>>().swap(normal);
  const double hmax = std::max(h[0], std::max(h[1], h[2]));
  const double rho = 0.5 * hmax;
  // Nodes farther than the accurate band (plus a voxel, as sq is measured to
  // band nodes) skip the neighbourhood search and the propagation.
  const double far = p.band > 0 ? p.band + 2 * hmax : kInf, far2 = far * far;
  const float rhof = float(rho);
  // Squared distance from x to disc b, or infinity when it is certainly >= bound
  // (the normal part alone is, which spares the square root).
  auto disc_d2_below = [&](const double x[3], std::int32_t b, double bound) {
    const Disc& D = disc[std::size_t(b)];
    const float v0 = float(double(D.p[0]) - x[0]), v1 = float(double(D.p[1]) - x[1]),
                v2 = float(double(D.p[2]) - x[2]);
    const float vv = v0 * v0 + v1 * v1 + v2 * v2;
    if (D.m[0] == 0 && D.m[1] == 0 && D.m[2] == 0) return double(vv);
    const float a = v0 * D.m[0] + v1 * D.m[1] + v2 * D.m[2];
    const float aa = a * a;
    if (double(aa) >= bound) return kInf;
    const float lat2 = std::max(0.f, vv - aa);
    if (lat2 <= rhof * rhof) return double(aa);
    const float lat = std::sqrt(lat2) - rhof;
    return double(aa + lat * lat);
  };
  auto disc_d2 = [&](const double x[3], std::int32_t b) { return disc_d2_below(x, b, kInf); };
  // Rows holding a node within the accurate band: the others take no part
  // in the propagation (step 4).
  std::vector<std::uint8_t> row_near(ny * nz, 0);
  // Neighbouring nodes mostly share their nearest band node, so each row
  // keeps the candidate discs of the last (band node, side) pair it used.
  const bool avx2 = cpu_has_avx2();
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    std::int32_t cand[27];
    int ncand = 0;
    std::size_t cached_site = std::size_t(-1);
    bool cached_side = false;
    // The candidates' discs side by side (one array per component), so that
    // a node's distances to all of them come from one loop the compiler
    // vectorises; the first strict minimum is the one the scalar search
    // with its early exits found (an exit only skips a disc that cannot be
    // nearer), the same float operations in the same order.
    alignas(32) float cp[3][kCandSlots] = {}, cm[3][kCandSlots] = {};
    alignas(32) float cd2[kCandSlots];
    for (std::size_t j = 0; j < ny; ++j)
      for (std::size_t i = 0; i < nx; ++i) {
        const std::size_t c = i + nx * j + nxy * k;
        const double x[3] = {double(i) * h[0], double(j) * h[1], double(k) * h[2]};
        const std::size_t s = std::size_t(site[c]);
        std::int32_t arg = band[s];
        if (double(sq[c]) > far2 && !(p.band_outside_only && below(c))) {  // beyond the accurate band: the nearest band node's disc
          sq[c] = float(disc_d2(x, arg));
          site[c] = -1 - arg;
          continue;
        }
        row_near[j + ny * k] = 1;
        const bool side = below(c);
        if (s != cached_site || side != cached_side) {
          cached_site = s;
          cached_side = side;
          ncand = 0;
          const std::size_t si = s % nx, sj = (s / nx) % ny, sk = s / nxy;
          for (std::size_t kk = sk > 0 ? sk - 1 : 0; kk <= std::min(sk + 1, nz - 1); ++kk)
            for (std::size_t jj = sj > 0 ? sj - 1 : 0; jj <= std::min(sj + 1, ny - 1); ++jj) {
              const std::int32_t* row = band.data() + nx * jj + nxy * kk;
              for (std::size_t ii = si > 0 ? si - 1 : 0; ii <= std::min(si + 1, nx - 1); ++ii) {
                const std::int32_t b = row[ii];
                if (b >= 0 && disc[std::size_t(b)].below == side) cand[ncand++] = b;
              }
            }
          for (int q = 0; q < ncand; ++q) {
            const Disc& D = disc[std::size_t(cand[q])];
            for (int a = 0; a < 3; ++a) {
              cp[a][q] = D.p[a];
              cm[a][q] = D.m[a];
            }
          }
        }
        candidate_distances(cp, cm, ncand, x, rhof, cd2, avx2);
        float best;  // the first strict minimum (+infinity and the nearest band node's id if none)
        const int q = first_minimum(cd2, ncand, best, avx2);
        if (q >= 0) arg = cand[q];
        site[c] = arg;
        sq[c] = best;
      }
  });

  // 4. Closest-point propagation along the axes (forward and backward): a
  //    node adopts a neighbour's disc when it is nearer. This removes most of
  //    the error of step 3 where the nearest band node is not the one whose
  //    disc is nearest (far from a tilted surface).
  //    Lines along x run one after the other; lines along y and z are swept
  //    a whole x-row at a time (each line still forward, then backward), so
  //    memory is read in contiguous rows. Nodes beyond the accurate band
  //    neither give nor take: rows without a node within it are skipped.
  auto relax = [&](std::size_t c, std::size_t from, const double x[3]) {
    const std::int32_t b = site[from];
    if (b == site[c] || b < 0 || site[c] < 0) return;
    const double d2 = disc_d2_below(x, b, double(sq[c]));
    if (d2 < double(sq[c])) {
      sq[c] = float(d2);
      site[c] = b;
    }
  };
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    for (std::size_t j = 0; j < ny; ++j) {
      if (!row_near[j + ny * k]) continue;
      const std::size_t base = nx * j + nxy * k;
      double x[3] = {0, double(j) * h[1], double(k) * h[2]};
      for (std::size_t t = 1; t < nx; ++t) {
        x[0] = double(t) * h[0];
        relax(base + t, base + t - 1, x);
      }
      for (std::size_t t = nx - 1; t-- > 0;) {
        x[0] = double(t) * h[0];
        relax(base + t, base + t + 1, x);
      }
    }
  });
  for (int axis = 1; axis < 3; ++axis) {
    const std::size_t len = counts[axis], st = stride[axis];
    const int other = axis == 1 ? 2 : 1;  // the line's fixed coordinate besides x
    pm::parallel_for(std::size_t(0), counts[other], [&](std::size_t u) {
      const std::size_t base = u * stride[other];
      double x[3];
      x[other] = double(u) * h[other];
      auto row_id = [&](std::size_t t) { return axis == 1 ? t + ny * u : u + ny * t; };
      auto row = [&](std::size_t at, std::size_t from) {
        if (!row_near[row_id(at)] || !row_near[row_id(from)]) return;
        x[axis] = double(at) * h[axis];
        for (std::size_t i = 0; i < nx; ++i) {
          x[0] = double(i) * h[0];
          relax(base + at * st + i, base + from * st + i, x);
        }
      };
      for (std::size_t t = 1; t < len; ++t) row(t, t - 1);
      for (std::size_t t = len - 1; t-- > 0;) row(t, t + 1);
    });
  }

  std::vector<float> out(n);
  pm::parallel_for(std::size_t(0), n, [&](std::size_t c) {
    const float d = std::sqrt(sq[c]);
    out[c] = below(c) ? -d : d;
  });
  return out;
}

Volume signed_distance(const Volume& field, const DistanceParams& p) {
  require_finite(field, "signed_distance: input");
  const std::vector<float> d = signed_distance(field.to_float(), field.dims(), field.geometry(), p);
  Volume out(VoxelType::f32, field.dims(), field.geometry());
  std::copy(d.begin(), d.end(), out.data<float>());
  return out;
}

Volume mask_signed_distance(const Volume& mask) {
  std::vector<float> f(mask.count());
  std::size_t inside = 0;
  for (std::size_t c = 0; c < f.size(); ++c) {
    const bool in = mask.get(c) != 0;
    inside += in;
    f[c] = in ? -0.5f : 0.5f;
  }
  if (inside == 0 || inside == f.size())
    throw InputError(std::string("mask_signed_distance: the mask is ") + (inside ? "full" : "empty") + " (" +
                     std::to_string(inside) + " of " + std::to_string(f.size()) +
                     " voxels inside); expected both inside and outside voxels");
  const std::vector<float> d = signed_distance(f, mask.dims(), mask.geometry(), {});
  Volume out(VoxelType::f32, mask.dims(), mask.geometry());
  std::copy(d.begin(), d.end(), out.data<float>());
  return out;
}

}  // namespace pm
