#include "pm/field/volume_field.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>
#include <sstream>
#include <utility>

#include <tbb/blocked_range.h>

#include "pm/base/error.h"
#include "pm/base/parallel.h"

#ifdef __linux__
#include <sys/mman.h>
#endif

// An AVX2 copy of the arithmetic, chosen at run time (the library itself is
// built for baseline x86-64; PM_AVX2_COPIES, pm/base/cpu.h).
#include "pm/base/cpu.h"
#if PM_AVX2_COPIES
#include <immintrin.h>
#endif
// Streaming (non-temporal) stores for the batch sort's scatter: SSE2.
#if defined(__SSE2__)
#define PM_STREAM_STORES 1
#include <emmintrin.h>
#else
#define PM_STREAM_STORES 0
#endif

namespace pm {

// Layout. The 4x4x4 taps of one evaluation at a random point touch 16 rows,
// about 19 cache lines, in a plain x-fastest array. Voxels are therefore
// stored in bricks of 4x2x2 floats (one 64-byte line, line-aligned), bricks in
// x-fastest order: the same taps touch 1.75 * 2.5 * 2.5 ~ 11 lines on average.
// Both the brick address and the position inside a brick are sums of one term
// per axis, so offset(i,j,k) = offset_[0][i] + offset_[1][j] + offset_[2][k]
// with three small tables; clamping to the border (replicate) is folded into
// the tables, so evaluation has no per-tap bounds checks at all.
//
// Evaluation is split in two: locate() turns a position into tap offsets and
// fractions and prefetches the lines; accumulate() does the arithmetic. A
// batch runs locate() kLookahead points ahead of accumulate(), so the cache
// misses of several evaluations overlap; a single point runs the same two
// functions back to back, so batch and single-point results are
// bit-identical by construction.
//
// Arithmetic. accumulate() sums in double, separably, with the four x taps as
// lanes: two SSE2 pairs on baseline x86-64, one AVX2 register when the CPU
// has it. Both do the same IEEE operations in the same order (multiplies and
// adds, no FMA), so the AVX2 path returns the very same bits; it only loads
// a row's four taps with one blend (one permute at the x border) instead of
// four scalar loads.

namespace {

using Index = std::ptrdiff_t;

constexpr Index kBrick[3] = {4, 2, 2};
constexpr Index kBrickSize = kBrick[0] * kBrick[1] * kBrick[2];  // floats per brick
constexpr Index kPad = 3;  // table entries before index 0 (taps reach i-1 >= -3)

// Points located ahead of the one being reconstructed in a batch. Measured
// (B-spline value+gradient, 256³ floats, uniformly random points, AMD EPYC
// VM, CPU time): 0 ahead 400 ns per point, 1: 250 ns, 2-3: 240 ns, 4-16:
// 270-330 ns. Each point has ~11 lines, so 2 ahead keeps ~20-30 misses in
// flight, about what one core's miss buffers hold.
constexpr std::size_t kLookahead = 2;
constexpr std::size_t kRing = 8;  // slots for located points, > kLookahead
static_assert(kRing > kLookahead, "the ring must hold the point being reconstructed and those ahead");

struct Grid {
  const float* data;
  const Index* off[3];  // off[a][i] for i in [-kPad, n_a + kPad]
  double hi[3];         // n_a + 1: beyond it (and below -2) all taps are clamped
};

// Where one evaluation reads: offsets of the four taps along each axis (a
// voxel's offset is the sum of one per axis) and the fractions u in [0, 1).
struct Taps {
  Index o[3][4];
  double u[3];
  bool nan;  // a coordinate was NaN: every result is NaN
};

// Index-space position t -> taps; then start every cache-line fetch, so that
// on a large volume the misses overlap (issued in program order the
// arithmetic between them would fill the reorder window and serialise them).
template <bool kPrefetch = true>
inline void locate(const Grid& gr, const double t_in[3], Taps& tp) {
  double t[3] = {t_in[0], t_in[1], t_in[2]};
  tp.nan = false;
  if (!(t[0] >= -2.0 && t[0] <= gr.hi[0] && t[1] >= -2.0 && t[1] <= gr.hi[1] &&
        t[2] >= -2.0 && t[2] <= gr.hi[2])) {
    for (int a = 0; a < 3; ++a) {
      if (std::isnan(t[a])) {
        tp.nan = true;
        t[a] = 0.0;  // keeps the offsets valid (prefetched, never used)
      }
      t[a] = t[a] < -2.0 ? -2.0 : (t[a] > gr.hi[a] ? gr.hi[a] : t[a]);
    }
  }
  for (int a = 0; a < 3; ++a) {
    // floor without libm: t is finite and in [-2, n+1] here.
    Index i = static_cast<Index>(t[a]);
    i -= t[a] < static_cast<double>(i) ? 1 : 0;
    tp.u[a] = t[a] - static_cast<double>(i);
    const Index* off = gr.off[a] + i - 1;
    tp.o[a][0] = off[0]; tp.o[a][1] = off[1]; tp.o[a][2] = off[2]; tp.o[a][3] = off[3];
  }
  // Taps {0,3} in x and {0,2,3} in y and z cover every brick (line) touched.
  static_assert(kBrick[0] == 4 && kBrick[1] == 2 && kBrick[2] == 2, "prefetch pattern assumes 4x2x2 bricks");
#if defined(__GNUC__)
  if constexpr (kPrefetch)
    for (int c : {0, 2, 3})
      for (int b : {0, 2, 3}) {
        const float* row = gr.data + tp.o[2][c] + tp.o[1][b];
        __builtin_prefetch(row + tp.o[0][0]);
        __builtin_prefetch(row + tp.o[0][3]);
      }
#endif
}

// Kernel weights for the three axes: wv value kernel, wd the derivative
// kernel's value weights (a copy of wv when the kernels agree), d1/d2 its
// first/second derivatives (only as far as Order needs).
template <KernelType V, KernelType D, int Order>
inline void weights(const double u[3], double wv[3][4], double wd[3][4], double d1[3][4], double d2[3][4]) {
  constexpr bool mixed = V != D;
  for (int a = 0; a < 3; ++a) {
    kernel_weights_fixed<V>(u[a], wv[a], nullptr, nullptr);
    if constexpr (Order >= 1) {
      kernel_weights_fixed<D>(u[a], mixed ? wd[a] : nullptr, d1[a], Order >= 2 ? d2[a] : nullptr);
      if constexpr (!mixed)
        for (int q = 0; q < 4; ++q) wd[a][q] = wv[a][q];
    }
  }
}

template <int Order>
inline double nan_results(double g[3], double h[6]) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if constexpr (Order >= 1) g[0] = g[1] = g[2] = nan;
  if constexpr (Order >= 2)
    for (int k = 0; k < 6; ++k) h[k] = nan;
  return nan;
}

// Four doubles, one per x tap, as two pairs: GCC/Clang vector extensions map
// a pair to one SSE2 register on baseline x86-64; a plain struct elsewhere.
#if defined(__GNUC__) && !defined(PM_NO_VECTOR_EXTENSIONS)
typedef double D2 __attribute__((vector_size(16)));
#else
struct D2 {
  double v[2] = {0, 0};
  double operator[](int i) const { return v[i]; }
  D2& operator+=(const D2& o) { v[0] += o.v[0]; v[1] += o.v[1]; return *this; }
};
inline D2 operator*(double s, const D2& a) { return D2{{s * a.v[0], s * a.v[1]}}; }
#endif
struct D4 {
  D2 lo, hi;
  D4& operator+=(const D4& o) {
    lo += o.lo;
    hi += o.hi;
    return *this;
  }
};
inline D4 operator*(double s, const D4& a) { return D4{s * a.lo, s * a.hi}; }
inline D4 gather4(const float* row, const Index o[4]) {
  return D4{D2{row[o[0]], row[o[1]]}, D2{row[o[2]], row[o[3]]}};
}
// acc = w r for the first term of a sum, acc + w r for the others: a sum
// started at w r rather than at 0 + w r (the same value, except that a
// first product of -0 stays -0), one add fewer per sum. Both code paths
// start their sums this way.
template <class T>
inline void add_term(T& acc, bool first, double w, const T& r) {
  if (first)
    acc = w * r;
  else
    acc += w * r;
}
inline double dot4(const double w[4], const D4& q) {
  return (w[0] * q.lo[0] + w[1] * q.lo[1]) + (w[2] * q.hi[0] + w[3] * q.hi[1]);
}

// Order 0: value; 1: + gradient; 2: + Hessian (h = xx, xy, xz, yy, yz, zz),
// all in index space. V is the value kernel, D the derivative kernel: the
// gradient and Hessian are those of the D-reconstruction (D's value weights
// on the axes not differentiated).
//
// Separable accumulation, y and z first with 4 lanes along x, x last:
// P* = one plane's rows weighted along y, Q** = planes weighted along y
// then z (first letter: y weights, second: z weights; v = value kernel,
// w = derivative kernel's value weights, 1/2 = its derivatives).
template <KernelType V, KernelType D, int Order>
double accumulate(const Grid& gr, const Taps& tp, double g[3], double h[6]) {
  if (tp.nan) return nan_results<Order>(g, h);
  constexpr bool mixed = V != D;
  double wv[3][4], wd[3][4], d1[3][4], d2[3][4];
  weights<V, D, Order>(tp.u, wv, wd, d1, d2);
  D4 Qvv = {}, Qww = {}, Q1w = {}, Qw1 = {}, Q2w = {}, Qw2 = {}, Q11 = {};
  for (int c = 0; c < 4; ++c) {
    D4 Pv = {}, Pw = {}, P1 = {}, P2 = {};
    for (int b = 0; b < 4; ++b) {
      const float* row = gr.data + tp.o[2][c] + tp.o[1][b];
      const D4 r = gather4(row, tp.o[0]);
      add_term(Pv, b == 0, wv[1][b], r);
      if constexpr (Order >= 1) {
        if constexpr (mixed) add_term(Pw, b == 0, wd[1][b], r);
        add_term(P1, b == 0, d1[1][b], r);
      }
      if constexpr (Order >= 2) add_term(P2, b == 0, d2[1][b], r);
    }
    add_term(Qvv, c == 0, wv[2][c], Pv);
    if constexpr (Order >= 1) {
      const D4& PW = mixed ? Pw : Pv;
      if constexpr (mixed) add_term(Qww, c == 0, wd[2][c], PW);
      add_term(Q1w, c == 0, wd[2][c], P1);
      add_term(Qw1, c == 0, d1[2][c], PW);
      if constexpr (Order >= 2) {
        add_term(Q2w, c == 0, wd[2][c], P2);
        add_term(Qw2, c == 0, d2[2][c], PW);
        add_term(Q11, c == 0, d1[2][c], P1);
      }
    }
  }
  const double f = dot4(wv[0], Qvv);
  if constexpr (Order >= 1) {
    const D4& QW = mixed ? Qww : Qvv;
    g[0] = dot4(d1[0], QW);
    g[1] = dot4(wd[0], Q1w);
    g[2] = dot4(wd[0], Qw1);
    if constexpr (Order >= 2) {
      h[0] = dot4(d2[0], QW);
      h[1] = dot4(d1[0], Q1w);
      h[2] = dot4(d1[0], Qw1);
      h[3] = dot4(wd[0], Q2w);
      h[4] = dot4(wd[0], Q11);
      h[5] = dot4(wd[0], Qw2);
    }
  }
  return f;
}

#if PM_AVX2_COPIES
// The same sums with the four x lanes in one AVX2 register. Every lane sees
// the operations of accumulate() in the same order (acc + w * r, no FMA), and
// dot4 adds (w0 q0 + w1 q1) + (w2 q2 + w3 q3) as there: identical results.
#define PM_AVX2 __attribute__((target("avx2"), always_inline)) inline
PM_AVX2 __m256d madd(__m256d acc, bool first, double w, __m256d r) {  // add_term()
  const __m256d p = _mm256_mul_pd(_mm256_set1_pd(w), r);
  return first ? p : _mm256_add_pd(acc, p);
}
// Blend path (see accumulate_avx2): lane q holds tap (q - s) mod 4, so tap t
// is in lane (t + s) mod 4; kRotate[s] moves it back to lane t (a pair of
// 32-bit indices per double).
alignas(32) constexpr int kRotate[4][8] = {
    {0, 1, 2, 3, 4, 5, 6, 7}, {2, 3, 4, 5, 6, 7, 0, 1}, {4, 5, 6, 7, 0, 1, 2, 3}, {6, 7, 0, 1, 2, 3, 4, 5}};
PM_AVX2 __m256d rotate_back(__m256i rot, __m256d q) {
  return _mm256_castps_pd(_mm256_permutevar8x32_ps(_mm256_castpd_ps(q), rot));
}

// kernel_weights_fixed() for the three axes at once, one axis per lane (u =
// u_x, u_y, u_z, 0): every expression as written there, the same operations
// in the same order, so each lane holds the very bits of the scalar code.
// w[q], d1[q], d2[q]: tap q of each axis.
PM_AVX2 __m256d bc(double c) { return _mm256_set1_pd(c); }
PM_AVX2 __m256d vmul(__m256d a, __m256d b) { return _mm256_mul_pd(a, b); }
PM_AVX2 __m256d vadd(__m256d a, __m256d b) { return _mm256_add_pd(a, b); }
PM_AVX2 __m256d vsub(__m256d a, __m256d b) { return _mm256_sub_pd(a, b); }
template <KernelType K>
PM_AVX2 void kernel_weights_avx2(__m256d u, __m256d* w, __m256d* d1, __m256d* d2) {
  const __m256d u2 = vmul(u, u), u3 = vmul(u2, u);
  if constexpr (K == KernelType::bspline) {
    if (w) {
      const __m256d v = vsub(bc(1.0), u);
      w[0] = vmul(vmul(vmul(v, v), v), bc(1.0 / 6.0));
      w[1] = vadd(vsub(vmul(bc(0.5), u3), u2), bc(2.0 / 3.0));
      w[2] = vadd(vadd(vadd(vmul(bc(-0.5), u3), vmul(bc(0.5), u2)), vmul(bc(0.5), u)), bc(1.0 / 6.0));
      w[3] = vmul(u3, bc(1.0 / 6.0));
    }
    if (d1) {
      const __m256d v = vsub(bc(1.0), u);
      d1[0] = vmul(vmul(bc(-0.5), v), v);
      d1[1] = vsub(vmul(bc(1.5), u2), vmul(bc(2.0), u));
      d1[2] = vadd(vadd(vmul(bc(-1.5), u2), u), bc(0.5));
      d1[3] = vmul(bc(0.5), u2);
    }
    if (d2) {
      d2[0] = vsub(bc(1.0), u);
      d2[1] = vsub(vmul(bc(3.0), u), bc(2.0));
      d2[2] = vsub(bc(1.0), vmul(bc(3.0), u));
      d2[3] = u;
    }
  } else {
    if (w) {
      const __m256d v = vsub(bc(1.0), u);
      w[0] = vmul(vmul(vmul(bc(-0.5), u), v), v);
      w[1] = vadd(vmul(bc(0.5), vsub(vmul(bc(3.0), u3), vmul(bc(5.0), u2))), bc(1.0));
      w[2] = vmul(vmul(bc(0.5), u), vsub(vadd(bc(1.0), vmul(bc(4.0), u)), vmul(bc(3.0), u2)));
      w[3] = vmul(vmul(bc(-0.5), u2), v);
    }
    if (d1) {
      d1[0] = vsub(vadd(vmul(bc(-1.5), u2), vmul(bc(2.0), u)), bc(0.5));
      d1[1] = vsub(vmul(bc(4.5), u2), vmul(bc(5.0), u));
      d1[2] = vadd(vadd(vmul(bc(-4.5), u2), vmul(bc(4.0), u)), bc(0.5));
      d1[3] = vsub(vmul(bc(1.5), u2), u);
    }
    if (d2) {
      d2[0] = vsub(bc(2.0), vmul(bc(3.0), u));
      d2[1] = vsub(vmul(bc(9.0), u), bc(5.0));
      d2[2] = vsub(bc(4.0), vmul(bc(9.0), u));
      d2[3] = vsub(vmul(bc(3.0), u), bc(1.0));
    }
  }
}
// t[q] holds tap q of the three axes (lanes x, y, z): to w[axis][tap].
PM_AVX2 void store_axes(const __m256d* t, double (*w)[4]) {
  const __m256d lo01 = _mm256_unpacklo_pd(t[0], t[1]), hi01 = _mm256_unpackhi_pd(t[0], t[1]);  // 0x 1x 0z 1z | 0y 1y
  const __m256d lo23 = _mm256_unpacklo_pd(t[2], t[3]), hi23 = _mm256_unpackhi_pd(t[2], t[3]);
  _mm256_storeu_pd(w[0], _mm256_permute2f128_pd(lo01, lo23, 0x20));
  _mm256_storeu_pd(w[1], _mm256_permute2f128_pd(hi01, hi23, 0x20));
  _mm256_storeu_pd(w[2], _mm256_permute2f128_pd(lo01, lo23, 0x31));
}
// weights() with the axes as lanes: the same values, bit for bit.
template <KernelType V, KernelType D, int Order>
PM_AVX2 void weights_avx2(const double u[3], double wv[3][4], double wd[3][4], double d1[3][4], double d2[3][4]) {
  constexpr bool mixed = V != D;
  const __m256d uu = _mm256_setr_pd(u[0], u[1], u[2], 0.0);
  __m256d tv[4], td[4], t1[4], t2[4];
  kernel_weights_avx2<V>(uu, tv, nullptr, nullptr);
  store_axes(tv, wv);
  if constexpr (Order >= 1) {
    kernel_weights_avx2<D>(uu, mixed ? td : nullptr, t1, Order >= 2 ? t2 : nullptr);
    store_axes(mixed ? td : tv, wd);
    store_axes(t1, d1);
    if constexpr (Order >= 2) store_axes(t2, d2);
  }
}
PM_AVX2 double dot4(const double w[4], __m256d q) {
  const __m256d m = _mm256_mul_pd(_mm256_loadu_pd(w), q);
  const __m128d s = _mm_hadd_pd(_mm256_castpd256_pd128(m), _mm256_extractf128_pd(m, 1));  // m0+m1, m2+m3
  return _mm_cvtsd_f64(_mm_add_sd(s, _mm_unpackhi_pd(s, s)));
}
// Four dot4()s at once, w_k . q_k in lane k, each summed as there:
// (w0 q0 + w1 q1) + (w2 q2 + w3 q3).
PM_AVX2 __m256d dot4x4(const double* w0, __m256d q0, const double* w1, __m256d q1, const double* w2, __m256d q2,
                       const double* w3, __m256d q3) {
  const __m256d h01 = _mm256_hadd_pd(_mm256_mul_pd(_mm256_loadu_pd(w0), q0), _mm256_mul_pd(_mm256_loadu_pd(w1), q1));
  const __m256d h23 = _mm256_hadd_pd(_mm256_mul_pd(_mm256_loadu_pd(w2), q2), _mm256_mul_pd(_mm256_loadu_pd(w3), q3));
  // h01 = 0:(w0q0+w1q1) 1:(w0q0+w1q1) 0:(w2q2+w3q3) 1:(w2q2+w3q3), with k:(...) the terms of dot k.
  return _mm256_add_pd(_mm256_permute2f128_pd(h01, h23, 0x20), _mm256_permute2f128_pd(h01, h23, 0x31));
}
#undef PM_AVX2

// The sums of accumulate() over one row layout: kBlend with the x taps in
// rotated lanes (see accumulate_avx2), else in order.
template <KernelType V, KernelType D, int Order, bool kBlend>
__attribute__((target("avx2"), always_inline)) inline double accumulate_rows_avx2(
    const Taps& tp, const double (&wv)[3][4], const double (&wd)[3][4], const double (&d1)[3][4],
    const double (&d2)[3][4], const float* base, const int (&lane)[4], double g[3], double h[6]) {
  constexpr bool mixed = V != D;
  __m256i pick;  // in order: lanes of the 8-float window
  __m128 from_next;  // rotated: lanes q < s come from the next brick
  if constexpr (kBlend)
    from_next = _mm_castsi128_ps(_mm_cmplt_epi32(_mm_setr_epi32(0, 1, 2, 3), _mm_set1_epi32(lane[0])));
  else
    pick = _mm256_setr_epi32(lane[0], lane[1], lane[2], lane[3], 0, 0, 0, 0);
  const __m256d zero = _mm256_setzero_pd();
  __m256d Qvv = zero, Qww = zero, Q1w = zero, Qw1 = zero, Q2w = zero, Qw2 = zero, Q11 = zero;
  for (int c = 0; c < 4; ++c) {
    __m256d Pv = zero, Pw = zero, P1 = zero, P2 = zero;
    for (int b = 0; b < 4; ++b) {
      const float* p = base + tp.o[2][c] + tp.o[1][b];
      __m256d r;
      if constexpr (kBlend) {
        r = _mm256_cvtps_pd(_mm_blendv_ps(_mm_loadu_ps(p), _mm_loadu_ps(p + kBrickSize), from_next));
      } else {
        const __m256 window =
            _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p)), _mm_loadu_ps(p + kBrickSize), 1);
        r = _mm256_cvtps_pd(_mm256_castps256_ps128(_mm256_permutevar8x32_ps(window, pick)));
      }
      Pv = madd(Pv, b == 0, wv[1][b], r);
      if constexpr (Order >= 1) {
        if constexpr (mixed) Pw = madd(Pw, b == 0, wd[1][b], r);
        P1 = madd(P1, b == 0, d1[1][b], r);
      }
      if constexpr (Order >= 2) P2 = madd(P2, b == 0, d2[1][b], r);
    }
    Qvv = madd(Qvv, c == 0, wv[2][c], Pv);
    if constexpr (Order >= 1) {
      const __m256d PW = mixed ? Pw : Pv;
      if constexpr (mixed) Qww = madd(Qww, c == 0, wd[2][c], PW);
      Q1w = madd(Q1w, c == 0, wd[2][c], P1);
      Qw1 = madd(Qw1, c == 0, d1[2][c], PW);
      if constexpr (Order >= 2) {
        Q2w = madd(Q2w, c == 0, wd[2][c], P2);
        Qw2 = madd(Qw2, c == 0, d2[2][c], PW);
        Q11 = madd(Q11, c == 0, d1[2][c], P1);
      }
    }
  }
  if constexpr (kBlend) {
    const __m256i rot = _mm256_load_si256(reinterpret_cast<const __m256i*>(kRotate[lane[0]]));
    Qvv = rotate_back(rot, Qvv);
    if constexpr (Order >= 1) {
      if constexpr (mixed) Qww = rotate_back(rot, Qww);
      Q1w = rotate_back(rot, Q1w);
      Qw1 = rotate_back(rot, Qw1);
      if constexpr (Order >= 2) {
        Q2w = rotate_back(rot, Q2w);
        Qw2 = rotate_back(rot, Qw2);
        Q11 = rotate_back(rot, Q11);
      }
    }
  }
  if constexpr (Order == 0) {
    return dot4(wv[0], Qvv);
  } else {
    const __m256d QW = mixed ? Qww : Qvv;
    alignas(32) double r[4];
    _mm256_store_pd(r, dot4x4(wv[0], Qvv, d1[0], QW, wd[0], Q1w, wd[0], Qw1));
    g[0] = r[1];
    g[1] = r[2];
    g[2] = r[3];
    if constexpr (Order >= 2) {
      _mm256_storeu_pd(h, dot4x4(d2[0], QW, d1[0], Q1w, d1[0], Qw1, wd[0], Q2w));
      h[4] = dot4(wd[0], Q11);
      h[5] = dot4(wd[0], Qw2);
    }
    return r[0];
  }
}

// The four x taps lie in the brick holding tap 0 (offsets bx .. bx+3) and
// possibly the next brick along x (bx+16 .. bx+19). Away from the x border
// (no clamped tap) tap q sits at position s + q of that row of the two
// bricks, s = position of tap 0: loading both rows and blending positions
// < s from the next brick puts every tap in a lane of its own, tap q in
// lane (s + q) mod 4; the sums run lane by lane as they are and the lanes
// are rotated back once at the end. At the border (repeated offsets) the
// row of both bricks is loaded as an 8-float window and the taps picked
// with one permute per row. Either way each lane sees the same operations:
// bit-identical. The second brick may be past the last one; the storage has
// one brick of padding for that.
template <KernelType V, KernelType D, int Order>
__attribute__((target("avx2"))) double accumulate_avx2(const Grid& gr, const Taps& tp, double g[3], double h[6]) {
  if (tp.nan) return nan_results<Order>(g, h);
  double wv[3][4], wd[3][4], d1[3][4], d2[3][4];
  weights_avx2<V, D, Order>(tp.u, wv, wd, d1, d2);
  const Index bx = tp.o[0][0] & ~(kBrick[0] - 1);
  int lane[4];
  for (int q = 0; q < 4; ++q) {
    const Index d = tp.o[0][q] - bx;
    lane[q] = int(d < kBrick[0] ? d : d - kBrickSize + kBrick[0]);
  }
  const float* base = gr.data + bx;
  if (lane[1] == lane[0] + 1 && lane[2] == lane[0] + 2 && lane[3] == lane[0] + 3)
    return accumulate_rows_avx2<V, D, Order, true>(tp, wv, wd, d1, d2, base, lane, g, h);
  return accumulate_rows_avx2<V, D, Order, false>(tp, wv, wd, d1, d2, base, lane, g, h);
}

#endif

// grad_world = D^{-T} grad_index (M = D^{-1}).
inline Vec3 gradient_to_world(const Mat3& M, const double g[3]) {
  return Vec3(M.m[0][0] * g[0] + M.m[1][0] * g[1] + M.m[2][0] * g[2],
              M.m[0][1] * g[0] + M.m[1][1] * g[1] + M.m[2][1] * g[2],
              M.m[0][2] * g[0] + M.m[1][2] * g[1] + M.m[2][2] * g[2]);
}

// H_world = D^{-T} H_index D^{-1}, built symmetric.
inline void hessian_to_world(const Mat3& M, const double h[6], Mat3& hess) {
  const double Hi[3][3] = {{h[0], h[1], h[2]}, {h[1], h[3], h[4]}, {h[2], h[4], h[5]}};
  double HM[3][3];  // H_index * D^{-1}
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      HM[r][c] = Hi[r][0] * M.m[0][c] + Hi[r][1] * M.m[1][c] + Hi[r][2] * M.m[2][c];
  for (int r = 0; r < 3; ++r)
    for (int c = r; c < 3; ++c) {
      const double s = M.m[0][r] * HM[0][c] + M.m[1][r] * HM[1][c] + M.m[2][r] * HM[2][c];
      hess.m[r][c] = s;
      hess.m[c][r] = s;
    }
}

struct Frame {
  Grid grid;
  Mat3 inv_dirs;  // world -> index
  Vec3 origin;
  std::size_t sort_min_batch;  // batches this large run in brick order
  bool sort_unless_coherent;   // automatic: not when the batch is in a coherent order already
  int key_bits;                // bits of the largest brick index
  std::size_t bricks;          // bricks in the volume
  bool avx2;                   // the CPU has AVX2 and the field may use it
};

inline void locate_world(const Frame& fr, const Vec3& x, Taps& tp) {
  const Vec3 t = fr.inv_dirs * (x - fr.origin);  // to_index() below repeats it
  const double ti[3] = {t.x, t.y, t.z};
  locate(fr.grid, ti, tp);
}

using AccumulateFn = double (*)(const Grid&, const Taps&, double*, double*);

// The software pipeline: point i + kLookahead is located (its lines
// prefetched) before point i is reconstructed. grad / hess are written only
// as far as Order asks.
template <int Order, AccumulateFn Acc>
void run_batch(const Frame& fr, const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) {
  Taps ring[kRing];
  for (std::size_t k = 0; k < n && k < kLookahead; ++k) locate_world(fr, x[k], ring[k]);
  for (std::size_t i = 0; i < n; ++i) {
    if (i + kLookahead < n) locate_world(fr, x[i + kLookahead], ring[(i + kLookahead) % kRing]);
    double g[3], h[6];
    f[i] = Acc(fr.grid, ring[i % kRing], g, h);
    if constexpr (Order >= 1) grad[i] = gradient_to_world(fr.inv_dirs, g);
    if constexpr (Order >= 2) hessian_to_world(fr.inv_dirs, h, hess[i]);
  }
}

// Locality order for large batches. Uniformly random points touch ~11 lines
// each, nearly all misses in a volume larger than the caches, and in the
// order given no two consecutive points share a line. A large batch is
// therefore evaluated in the memory order of the bricks its points fall in
// (the brick of the voxel the point lies in, x-fastest brick order): points
// whose taps share lines run one after another, and the lines of a brick
// plane are still cached when the next plane needs them. A two-digit radix
// sort (most significant digit first) orders items that carry the point's
// index-space position, computed by the very expression locate_world()
// uses, so evaluation reads the items in order instead of the caller's
// array at random; each range of the first digit is sorted by the second
// into a small buffer that stays in cache (reused range after range) and
// evaluated at once. Value and gradient go back into the item's slot of the
// first-digit order (its range was just read, so that is in cache too) and
// a final pass copies them to the caller's positions, one random read per
// point (reads at random, writes in order: cheaper than writing the outputs
// at random). The order changes no arithmetic: results stay
// bit-identical to the single-point call. Measured on 256³ (1M bricks),
// B-spline value+gradient at uniformly random points, busy 2-core VM: the
// sort pays from ~128k points (1 per 8 bricks) and doubles the rate at 1M.
constexpr std::size_t kSortChunk = std::size_t(1) << 20;  // points sorted together at most
constexpr int kMaxKeyBits = 20;  // bits of the brick index kept at most (finer: low bits dropped)
constexpr std::size_t kFar = 16;  // the gather prefetches this many points ahead
constexpr std::size_t kAhead = 8;  // evaluation in brick order prefetches Hessian slots this many points ahead

// A point in the sort: its index-space position and its slot in the
// first-digit order; after evaluation that slot holds its value and
// gradient.
union SortItem {
  struct {
    double t[3];        // index-space position
    std::uint32_t idx;  // slot in the first-digit order (s.b)
    std::uint32_t low;  // low digit of the key
  } in;
  struct {
    double f, g[3];  // world gradient
  } out;
};
static_assert(sizeof(SortItem) == 32, "two items per cache line");
static_assert(sizeof(Vec3) == 3 * sizeof(double), "gather_results streams a gradient as three doubles");

// Per-thread scratch of the sort (the batch calls are const and may run
// concurrently from several threads; each runs one batch at a time). One
// block, grown to the largest chunk sorted on the thread (68 bytes per
// point, 140 with Hessians: 68 / 140 MiB for 2^20 points) and kept for
// reuse; on transparent huge pages where Linux grants them, as the gather
// reads it at random. The range buffer `a` has room for a whole chunk, as
// clustered points may all fall in one range.
class SortScratch {
 public:
  SortScratch() = default;
  SortScratch(const SortScratch&) = delete;
  SortScratch& operator=(const SortScratch&) = delete;
  ~SortScratch() { std::free(mem_); }
  // Room for n points, and their Hessians if asked (throws std::bad_alloc).
  void reserve(std::size_t n, bool hessians) {
    if (n <= cap_ && (!hessians || hess)) return;
    constexpr std::size_t huge = std::size_t(2) << 20;
    const std::size_t per_point =
        2 * sizeof(SortItem) + sizeof(std::uint32_t) + (hessians ? sizeof(Mat3) : std::size_t(0));
    const std::size_t n2 = (n + 1) / 2 * 2;  // b starts on a cache line
    const std::size_t bytes = (n2 * per_point + huge - 1) / huge * huge;
    std::free(mem_);
    mem_ = nullptr;
    cap_ = 0;
    mem_ = std::aligned_alloc(huge, bytes);
    if (!mem_) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    madvise(mem_, bytes, MADV_HUGEPAGE);
#endif
    a = static_cast<SortItem*>(mem_);
    b = a + n2;
    hess = hessians ? reinterpret_cast<Mat3*>(b + n2) : nullptr;
    key = reinterpret_cast<std::uint32_t*>(hessians ? static_cast<void*>(hess + n2) : static_cast<void*>(b + n2));
    cap_ = n;
  }
  SortItem* a = nullptr;          // one range of b sorted by the second digit, at a[0 ..)
  SortItem* b = nullptr;          // items sorted by the first digit; then their results
  Mat3* hess = nullptr;           // Hessians in the order of b
  std::uint32_t* key = nullptr;   // bucket keys, then each point's place in b
  std::vector<std::uint32_t> low_count;

 private:
  void* mem_ = nullptr;
  std::size_t cap_ = 0;
};
SortScratch& sort_scratch() {
  thread_local SortScratch s;
  return s;
}

// Index-space position of x, by the very expression locate_world() uses.
inline Vec3 to_index(const Frame& fr, const Vec3& x) { return fr.inv_dirs * (x - fr.origin); }

constexpr int kHighBits = 8;  // first digit: 256 ranges of the brick array

// The sort's first digit: the key keeps log2(n) + 2 high bits of the brick
// index, at most kMaxKeyBits (finer order has nothing left to gain), split
// into a high digit of up to kHighBits and a low digit.
struct SortPlan {
  int shift, high, low;
  std::uint32_t end[(std::size_t(1) << kHighBits) + 1];  // range d of the first digit ends at end[d]
};

#if PM_AVX2_COPIES
// Index-space positions of the four points p[0..4): to_index()'s operations
// in its order, one point per lane (the same bits): t[a] = axis a.
struct IndexMap4 {
  __m256d m[3][3], o[3];
  __attribute__((target("avx2"))) explicit IndexMap4(const Frame& fr) {
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) m[a][b] = _mm256_set1_pd(fr.inv_dirs.m[a][b]);
      o[a] = _mm256_set1_pd(fr.origin[a]);
    }
  }
  __attribute__((target("avx2"), always_inline)) inline void operator()(const Vec3* p, __m256d t[3]) const {
    static_assert(sizeof(Vec3) == 3 * sizeof(double), "four points are twelve doubles");
    // Twelve doubles x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3 to X, Y, Z.
    const double* q = &p->x;
    const __m256d a = _mm256_loadu_pd(q), b = _mm256_loadu_pd(q + 4), c = _mm256_loadu_pd(q + 8);
    const __m256d m1 = _mm256_blend_pd(a, b, 0xc);          // x0 y0 x2 y2
    const __m256d m2 = _mm256_permute2f128_pd(a, c, 0x21);  // z0 x1 z2 x3
    const __m256d m3 = _mm256_blend_pd(b, c, 0xc);          // y1 z1 y3 z3
    const __m256d d[3] = {_mm256_sub_pd(_mm256_shuffle_pd(m1, m2, 0xa), o[0]),
                          _mm256_sub_pd(_mm256_shuffle_pd(m1, m3, 0x5), o[1]),
                          _mm256_sub_pd(_mm256_shuffle_pd(m2, m3, 0xa), o[2])};
    for (int r = 0; r < 3; ++r)  // dot(row r, d): (r0 d0 + r1 d1) + r2 d2
      t[r] = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(m[r][0], d[0]), _mm256_mul_pd(m[r][1], d[1])),
                           _mm256_mul_pd(m[r][2], d[2]));
  }
};

// The first pass of sort_first_digit() four points at a time: key[i] (the
// same keys) and the histogram of their high digits. Returns how many points
// it did (a multiple of four); the caller does the rest. Only for brick
// indices below 2^31.
__attribute__((target("avx2"), noinline)) std::size_t brick_keys_avx2(const Frame& fr, const Vec3* x, std::size_t n,
                                                                     int shift, int low, std::uint32_t* key,
                                                                     std::uint32_t* count) {
  const IndexMap4 to_index4(fr);
  const __m256d lo = _mm256_set1_pd(-2.0);
  __m256d hi[3];
  __m128i top[3];  // n_a - 1
  std::int32_t nb[3];
  for (int a = 0; a < 3; ++a) {
    hi[a] = _mm256_set1_pd(fr.grid.hi[a]);
    const std::int32_t na = std::int32_t(fr.grid.hi[a]) - 1;
    top[a] = _mm_set1_epi32(na - 1);
    nb[a] = (na + std::int32_t(kBrick[a]) - 1) / std::int32_t(kBrick[a]);
  }
  const __m128i zero = _mm_setzero_si128(), nbx = _mm_set1_epi32(nb[0]), nby = _mm_set1_epi32(nb[1]);
  const __m128i sh = _mm_cvtsi32_si128(shift);
  const std::size_t end = n & ~std::size_t(3);
  for (std::size_t i = 0; i < end; i += 4) {
    __m256d ts[3];
    to_index4(x + i, ts);
    __m128i idx[3];
    for (int r = 0; r < 3; ++r) {
      const __m256d t = _mm256_min_pd(_mm256_max_pd(ts[r], lo), hi[r]);  // NaN -> -2, as in the scalar pass
      const __m128i v = _mm256_cvttpd_epi32(t);
      idx[r] = _mm_min_epi32(_mm_max_epi32(v, zero), top[r]);
    }
    const __m128i bx = _mm_srli_epi32(idx[0], 2), by = _mm_srli_epi32(idx[1], 1), bz = _mm_srli_epi32(idx[2], 1);
    const __m128i brick = _mm_add_epi32(bx, _mm_mullo_epi32(nbx, _mm_add_epi32(by, _mm_mullo_epi32(nby, bz))));
    const __m128i k = _mm_srl_epi32(brick, sh);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(key + i), k);
    ++count[(std::uint32_t(_mm_extract_epi32(k, 0)) >> low) + 1];
    ++count[(std::uint32_t(_mm_extract_epi32(k, 1)) >> low) + 1];
    ++count[(std::uint32_t(_mm_extract_epi32(k, 2)) >> low) + 1];
    ++count[(std::uint32_t(_mm_extract_epi32(k, 3)) >> low) + 1];
  }
  return end;
}

// The scatter of sort_first_digit() four points at a time, each item one
// AVX2 register (positions from IndexMap4: the same bits). Returns how many
// points it did (a multiple of four); the caller does the rest.
__attribute__((target("avx2"), noinline)) std::size_t scatter_avx2(const Frame& fr, const Vec3* x, std::size_t n,
                                                                  int low, std::uint32_t* key, std::uint32_t* count,
                                                                  const std::uint32_t* start, SortItem* pending,
                                                                  SortItem* b) {
  static_assert(offsetof(SortItem, in.idx) == 24 && offsetof(SortItem, in.low) == 28, "idx, low: the fourth double");
  const IndexMap4 to_index4(fr);
  const std::uint32_t low_mask = (std::uint32_t(1) << low) - 1;
  const std::size_t end = n & ~std::size_t(3);
  for (std::size_t i = 0; i < end; i += 4) {
    __m256d t[3];
    to_index4(x + i, t);
    std::uint64_t tail[4];  // idx | low << 32, as the item's last 8 bytes
    std::uint32_t d[4], j[4];
    for (int q = 0; q < 4; ++q) {
      const std::uint32_t k = key[i + q];
      d[q] = k >> low;
      j[q] = count[d[q]]++;
      tail[q] = std::uint64_t(j[q]) | (std::uint64_t(k & low_mask) << 32);
      key[i + q] = j[q];  // its place
    }
    const __m256d w = _mm256_castsi256_pd(_mm256_setr_epi64x(static_cast<long long>(tail[0]), static_cast<long long>(tail[1]),
                                                              static_cast<long long>(tail[2]), static_cast<long long>(tail[3])));
    const __m256d lo01 = _mm256_unpacklo_pd(t[0], t[1]), hi01 = _mm256_unpackhi_pd(t[0], t[1]);
    const __m256d lo2w = _mm256_unpacklo_pd(t[2], w), hi2w = _mm256_unpackhi_pd(t[2], w);
    const __m256d item[4] = {_mm256_permute2f128_pd(lo01, lo2w, 0x20), _mm256_permute2f128_pd(hi01, hi2w, 0x20),
                             _mm256_permute2f128_pd(lo01, lo2w, 0x31), _mm256_permute2f128_pd(hi01, hi2w, 0x31)};
    for (int q = 0; q < 4; ++q) {  // as the scalar scatter: whole lines streamed, pairs of items
      double* slot = reinterpret_cast<double*>(b + j[q]);
      if ((j[q] & 1) == 0) {
        _mm256_store_pd(reinterpret_cast<double*>(pending + d[q]), item[q]);
      } else if (j[q] - 1 >= start[d[q]]) {
        _mm256_stream_pd(slot - 4, _mm256_load_pd(reinterpret_cast<const double*>(pending + d[q])));
        _mm256_stream_pd(slot, item[q]);
      } else {
        _mm256_store_pd(slot, item[q]);
      }
    }
  }
  return end;
}
#endif

// Sorts the points x[0..n) (n <= kSortChunk) by the high digit of their brick
// key into s.b, each item with its low digit, and sets s.key[i] to where
// point i went. Two passes over x: keys and their histogram, then each
// point's position straight to its range. Not inlined into the evaluation
// copies: one copy serves all.
__attribute__((noinline)) void sort_first_digit(const Frame& fr, const Vec3* x, std::size_t n, bool hessians,
                                                SortScratch& s, SortPlan& plan) {
  s.reserve(n, hessians);
  int log2n = 0;
  while ((std::size_t(1) << log2n) < n) ++log2n;
  int bits = log2n + 2 < kMaxKeyBits ? log2n + 2 : kMaxKeyBits;
  bits = bits < fr.key_bits ? bits : fr.key_bits;
  plan.shift = fr.key_bits - bits;
  plan.high = bits < kHighBits ? bits : kHighBits;
  plan.low = bits - plan.high;
  const int low = plan.low;
  const std::uint32_t low_mask = (std::uint32_t(1) << low) - 1;
  std::uint32_t* count = plan.end;
  std::fill(count, count + (std::size_t(1) << plan.high) + 1, 0u);
  std::uint32_t* key = s.key;
  std::size_t first = 0;
#if PM_AVX2_COPIES
  if (fr.avx2 && fr.bricks < (std::size_t(1) << 31)) first = brick_keys_avx2(fr, x, n, plan.shift, low, key, count);
#endif
  for (std::size_t i = first; i < n; ++i) {
    // The brick of voxel trunc(t) after clamping t to [-2, n+1] (NaN to -2):
    // only the order depends on it.
    const Vec3 t = to_index(fr, x[i]);
    const double ti[3] = {t.x, t.y, t.z};
    Index off = 0;
    for (int a = 0; a < 3; ++a) {
      double c = ti[a] > -2.0 ? ti[a] : -2.0;
      c = c < fr.grid.hi[a] ? c : fr.grid.hi[a];
      off += fr.grid.off[a][static_cast<Index>(c)];
    }
    key[i] = std::uint32_t((std::uint64_t(off) / std::uint64_t(kBrickSize)) >> plan.shift);
    ++count[(key[i] >> low) + 1];
  }
  for (std::size_t d = 1; d <= (std::size_t(1) << plan.high); ++d) count[d] += count[d - 1];
  // count[d] is where range d starts; the scatter moves it to where it ends.
  // The scatter writes each range's items in order, two per cache line: the
  // first waits in `pending` and the pair goes out as one whole line with
  // streaming stores (no read of the line before it is written). Items whose
  // line is shared with the neighbouring range are stored normally.
  SortItem* b = s.b;
  std::uint32_t* place = key;  // each key is read just before its slot is overwritten
  std::uint32_t start[std::size_t(1) << kHighBits];
  std::copy(count, count + (std::size_t(1) << plan.high), start);
  alignas(64) SortItem pending[std::size_t(1) << kHighBits];
  first = 0;
#if PM_AVX2_COPIES && PM_STREAM_STORES
  if (fr.avx2) first = scatter_avx2(fr, x, n, low, key, count, start, pending, b);
#endif
  for (std::size_t i = first; i < n; ++i) {
    const std::uint32_t k = key[i], d = k >> low, j = count[d]++;
    SortItem it;
    const Vec3 t = to_index(fr, x[i]);
    it.in.t[0] = t.x;
    it.in.t[1] = t.y;
    it.in.t[2] = t.z;
    it.in.idx = j;
    it.in.low = k & low_mask;
    place[i] = j;
#if PM_STREAM_STORES
    if ((j & 1) == 0) {
      pending[d] = it;
    } else if (j - 1 >= start[d]) {
      __m128i* line = reinterpret_cast<__m128i*>(b + j - 1);
      const __m128i* first = reinterpret_cast<const __m128i*>(pending + d);
      const __m128i* second = reinterpret_cast<const __m128i*>(&it);
      _mm_stream_si128(line, _mm_load_si128(first));
      _mm_stream_si128(line + 1, _mm_load_si128(first + 1));
      _mm_stream_si128(line + 2, _mm_loadu_si128(second));
      _mm_stream_si128(line + 3, _mm_loadu_si128(second + 1));
    } else {
      b[j] = it;
    }
#else
    b[j] = it;
#endif
  }
#if PM_STREAM_STORES
  _mm_sfence();
  for (std::size_t d = 0; d < (std::size_t(1) << plan.high); ++d)  // a range's last item alone in its line
    if (count[d] > start[d] && ((count[d] - 1) & 1) == 0) b[count[d] - 1] = pending[d];
#endif
}

// Sorts range [begin, end) of s.b by the low digit into s.a[0 .. end -
// begin) and returns s.a. The same buffer serves every range: a range is a
// few thousand points at most for uniform points, so it stays in cache for
// the evaluation that follows.
__attribute__((noinline)) SortItem* sort_range(SortScratch& s, int low, std::size_t begin, std::size_t end) {
  SortItem *a = s.a, *b = s.b;
  std::vector<std::uint32_t>& lc = s.low_count;
  lc.assign(std::size_t(1) << low, 0u);
  for (std::size_t i = begin; i < end; ++i) ++lc[b[i].in.low];
  std::uint32_t sum = 0;
  for (std::uint32_t& c : lc) {
    const std::uint32_t m = c;
    c = sum;
    sum += m;
  }
  for (std::size_t i = begin; i < end; ++i) a[lc[b[i].in.low]++] = b[i];
  return a;
}

// The pipeline of run_batch over sorted items: item i + kLookahead is
// located before item i is reconstructed; value and gradient go to the
// item's slot in `out` (s.b: in.idx; `items` may be that very array, an
// item's position being no longer needed once located), the Hessian to
// hess[in.idx]. Without Prefetch, locate() issues no prefetches: with a
// point per brick or more the lines are mostly cached already and the
// hardware prefetcher follows the order (measured: faster at 1 point per
// brick, slower at 1 per 4).
template <int Order, AccumulateFn Acc, bool Prefetch>
void evaluate_sorted(const Frame& fr, const SortItem* items, std::size_t n, SortItem* out, Mat3* hess) {
  Taps ring[kRing];
  for (std::size_t k = 0; k < n && k < kLookahead; ++k) locate<Prefetch>(fr.grid, items[k].in.t, ring[k]);
  for (std::size_t i = 0; i < n; ++i) {
    if (i + kLookahead < n)
      locate<Prefetch>(fr.grid, items[i + kLookahead].in.t, ring[(i + kLookahead) % kRing]);
#if defined(__GNUC__)
    if constexpr (Order >= 2)  // the Hessians' slots are written in random order: fetch them early
      if (i + kAhead < n) {
        const Mat3* hp = hess + items[i + kAhead].in.idx;
        __builtin_prefetch(hp, 1);
        __builtin_prefetch(reinterpret_cast<const char*>(hp) + sizeof(Mat3) - 1, 1);
      }
#endif
    const std::uint32_t slot = items[i].in.idx;
    double g[3], h[6];
    const double f = Acc(fr.grid, ring[i % kRing], g, h);
    if constexpr (Order >= 2) hessian_to_world(fr.inv_dirs, h, hess[slot]);
    SortItem& o = out[slot];
    o.out.f = f;
    if constexpr (Order >= 1) {
      const Vec3 gw = gradient_to_world(fr.inv_dirs, g);
      o.out.g[0] = gw.x;
      o.out.g[1] = gw.y;
      o.out.g[2] = gw.z;
    }
  }
}

// Outputs of more points than this go out with streaming stores (values and
// gradients: 32 bytes a point, 4 MiB here, larger than a core's share of the
// caches): no read of each output line before it is written (measured at
// 1M points: the copy back about 10 -> 9 ns a point).
constexpr std::size_t kStreamOutputs = std::size_t(1) << 17;

// Results back to the caller's order: point i's results are in
// items[place[i]] (and hs[place[i]]). Reads the items (and Hessians) at
// random, one line each, two for a Hessian, prefetched; writes the outputs
// in order, with streaming stores when kStream.
template <int Order, bool kStream>
void gather_loop(const SortItem* items, const Mat3* hs, const std::uint32_t* place, std::size_t n, double* f,
                 Vec3* grad, Mat3* hess) {
  for (std::size_t i = 0; i < n; ++i) {
#if defined(__GNUC__)
    if (i + kFar < n) {
      const std::size_t j = place[i + kFar];
      __builtin_prefetch(items + j);
      if constexpr (Order >= 2) {
        __builtin_prefetch(hs + j);
        __builtin_prefetch(reinterpret_cast<const char*>(hs + j) + sizeof(Mat3) - 1);
      }
    }
#endif
    const std::size_t j = place[i];
    if constexpr (kStream) {
#if PM_STREAM_STORES && defined(__x86_64__)
      long long r[4];  // f, g: the bits, copied as they are
      std::memcpy(r, &items[j].out, sizeof r);
      _mm_stream_si64(reinterpret_cast<long long*>(f + i), r[0]);
      if constexpr (Order >= 1) {
        long long* gi = reinterpret_cast<long long*>(grad + i);
        _mm_stream_si64(gi, r[1]);
        _mm_stream_si64(gi + 1, r[2]);
        _mm_stream_si64(gi + 2, r[3]);
      }
#endif
    } else {
      const SortItem& it = items[j];
      f[i] = it.out.f;
      if constexpr (Order >= 1) grad[i] = Vec3(it.out.g[0], it.out.g[1], it.out.g[2]);
    }
    if constexpr (Order >= 2) hess[i] = hs[j];
  }
#if PM_STREAM_STORES && defined(__x86_64__)
  if constexpr (kStream) _mm_sfence();
#endif
}

template <int Order>
void gather_results(const SortItem* items, const Mat3* hs, const std::uint32_t* place, std::size_t n, double* f,
                    Vec3* grad, Mat3* hess) {
#if PM_STREAM_STORES && defined(__x86_64__)
  if (n > kStreamOutputs) return gather_loop<Order, true>(items, hs, place, n, f, grad, hess);
#endif
  gather_loop<Order, false>(items, hs, place, n, f, grad, hess);
}

// One chunk of at most kSortChunk points: sort, evaluate, gather.
template <int Order, AccumulateFn Acc, bool Prefetch>
void run_sorted_chunk(const Frame& fr, const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess,
                      SortScratch& s) {
  SortPlan plan;
  sort_first_digit(fr, x, n, Order >= 2, s, plan);
  if (plan.low == 0) {  // one digit: sorted
    evaluate_sorted<Order, Acc, Prefetch>(fr, s.b, n, s.b, s.hess);
  } else {
    // Each range by its low digit, then evaluated while it is in cache.
    for (std::size_t d = 0, begin = 0; d < (std::size_t(1) << plan.high); begin = plan.end[d++]) {
      const std::size_t m = plan.end[d] - begin;
      if (m == 1)
        evaluate_sorted<Order, Acc, Prefetch>(fr, s.b + begin, 1, s.b, s.hess);
      else if (m > 1)
        evaluate_sorted<Order, Acc, Prefetch>(fr, sort_range(s, plan.low, begin, plan.end[d]), m, s.b, s.hess);
    }
  }
  gather_results<Order>(s.b, s.hess, s.key, n, f, grad, hess);
}

// True when the points x[0..n) already come in a coherent order (mostly
// consecutive points within two voxels of each other along every axis, so
// that they share cache lines), judged on 64 pairs spread over the batch:
// sorting would then cost time and gain nothing (measured: a random walk of
// 1M points 9 -> 7 M/s).
__attribute__((noinline)) bool coherent(const Frame& fr, const Vec3* x, std::size_t n) {
  constexpr std::size_t kPairs = 64;
  const std::size_t pairs = n - 1 < kPairs ? n - 1 : kPairs;
  std::size_t close = 0;
  for (std::size_t k = 0; k < pairs; ++k) {
    const std::size_t i = k * (n - 1) / pairs;
    const Vec3 d = to_index(fr, x[i + 1]) - to_index(fr, x[i]);
    close += std::fabs(d.x) < 2.0 && std::fabs(d.y) < 2.0 && std::fabs(d.z) < 2.0;
  }
  return 4 * close >= 3 * pairs;
}

template <int Order, AccumulateFn Acc>
void run_sorted(const Frame& fr, const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) {
  SortScratch& s = sort_scratch();
  for (std::size_t at = 0; at < n; at += kSortChunk) {
    const std::size_t m = n - at < kSortChunk ? n - at : kSortChunk;
    Vec3* g = Order >= 1 ? grad + at : nullptr;
    Mat3* h = Order >= 2 ? hess + at : nullptr;
    if (m >= fr.bricks)
      run_sorted_chunk<Order, Acc, false>(fr, x + at, m, f + at, g, h, s);
    else
      run_sorted_chunk<Order, Acc, true>(fr, x + at, m, f + at, g, h, s);
  }
}

// One point (n == 1): the same steps without the ring.
template <int Order, AccumulateFn Acc>
void run_single(const Frame& fr, const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) {
  if (n >= fr.sort_min_batch && n >= 2 && !(fr.sort_unless_coherent && coherent(fr, x, n)))
    return run_sorted<Order, Acc>(fr, x, n, f, grad, hess);
  if (n != 1) return run_batch<Order, Acc>(fr, x, n, f, grad, hess);
  Taps tp;
  locate_world(fr, *x, tp);
  double g[3], h[6];
  *f = Acc(fr.grid, tp, g, h);
  if constexpr (Order >= 1) *grad = gradient_to_world(fr.inv_dirs, g);
  if constexpr (Order >= 2) hessian_to_world(fr.inv_dirs, h, *hess);
}

// Entry points, one per kernel pair, order and code path: everything above
// inlined into one function (flatten), so the AVX2 copy is AVX2 throughout.
template <KernelType V, KernelType D, int Order>
__attribute__((flatten)) void eval_baseline(const Frame& fr, const Vec3* x, std::size_t n, double* f, Vec3* grad,
                                            Mat3* hess) {
  run_single<Order, accumulate<V, D, Order>>(fr, x, n, f, grad, hess);
}

#if PM_AVX2_COPIES
template <KernelType V, KernelType D, int Order>
__attribute__((target("avx2"), flatten)) void eval_avx2(const Frame& fr, const Vec3* x, std::size_t n, double* f,
                                                        Vec3* grad, Mat3* hess) {
  run_single<Order, accumulate_avx2<V, D, Order>>(fr, x, n, f, grad, hess);
}
#endif

template <int Order>
void dispatch(const VolumeFieldParams& p, bool avx2, const Frame& fr, const Vec3* x, std::size_t n,
              double* f, Vec3* grad, Mat3* hess) {
  constexpr KernelType B = KernelType::bspline, C = KernelType::catmull_rom;
  const bool vb = p.value_kernel == B, db = p.deriv_kernel == B;
#if PM_AVX2_COPIES
  if (avx2) {
    if (vb)
      db ? eval_avx2<B, B, Order>(fr, x, n, f, grad, hess) : eval_avx2<B, C, Order>(fr, x, n, f, grad, hess);
    else
      db ? eval_avx2<C, B, Order>(fr, x, n, f, grad, hess) : eval_avx2<C, C, Order>(fr, x, n, f, grad, hess);
    return;
  }
#else
  (void)avx2;
#endif
  if (vb)
    db ? eval_baseline<B, B, Order>(fr, x, n, f, grad, hess) : eval_baseline<B, C, Order>(fr, x, n, f, grad, hess);
  else
    db ? eval_baseline<C, B, Order>(fr, x, n, f, grad, hess) : eval_baseline<C, C, Order>(fr, x, n, f, grad, hess);
}

// Reserve n floats plus room to align the start to a 64-byte line, and ask
// Linux for transparent huge pages before the buffer is first touched (random
// access over a large volume otherwise misses the TLB on most taps; a hint
// only, without effect where THP is disabled). Returns the aligned start.
std::size_t reserve_voxels(std::vector<float>& data, std::size_t n) {
  data.reserve(n + kBrickSize);
  const auto begin = reinterpret_cast<std::uintptr_t>(data.data());
  const std::size_t base = ((64 - begin % 64) % 64) / sizeof(float);
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t huge = std::uintptr_t(2) << 20;
  const std::uintptr_t end = begin + (n + kBrickSize) * sizeof(float);
  const std::uintptr_t lo = (begin + huge - 1) & ~(huge - 1), hi = end & ~(huge - 1);
  if (hi > lo) madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
#endif
  return base;
}

}  // namespace

VolumeField::VolumeField(const Volume& v, VolumeFieldParams p, std::string name)
    : dims_(v.dims()), geom_(v.geometry()), params_(p), name_(std::move(name)) {
  const std::string what = "VolumeField: volume " + quote(name_);
  if (v.empty()) throw InputError(what + ": volume is empty; expected at least one voxel");
  const double det = determinant(geom_.directions);
  if (!(std::fabs(det) > 0) || !std::isfinite(det))
    throw InputError(what + ": space directions are singular or non-finite; expected three independent axes");
  inv_dirs_ = inverse(geom_.directions);
  avx2_ = params_.allow_avx2 && cpu_has_avx2();

  // Offset tables (bricks of kBrick, brick grid x-fastest), clamped indices.
  Index bricks[3], brick_stride[3];
  for (int a = 0; a < 3; ++a) bricks[a] = (Index(dims_[a]) + kBrick[a] - 1) / kBrick[a];
  brick_stride[0] = kBrickSize;
  brick_stride[1] = kBrickSize * bricks[0];
  brick_stride[2] = kBrickSize * bricks[0] * bricks[1];
  const Index inner_stride[3] = {1, kBrick[0], kBrick[0] * kBrick[1]};
  for (int a = 0; a < 3; ++a) {
    const Index n = Index(dims_[a]);
    offset_[a].resize(std::size_t(n + 2 * kPad + 1));
    for (Index i = -kPad; i <= n + kPad; ++i) {
      const Index c = i < 0 ? 0 : (i >= n ? n - 1 : i);
      offset_[a][std::size_t(i + kPad)] =
          (c / kBrick[a]) * brick_stride[a] + (c % kBrick[a]) * inner_stride[a];
    }
  }

  // One brick of zeros after the last: the AVX2 path loads a row of the brick
  // after the one holding the first x tap even when no tap lies in it.
  const std::size_t stored = std::size_t(bricks[0] * bricks[1] * bricks[2] * kBrickSize) + kBrickSize;
  // Brick order for batches (see run_sorted): automatic, from one point per
  // four bricks on volumes larger than common last-level caches.
  const std::size_t brick_count = std::size_t(bricks[0] * bricks[1] * bricks[2]);
  bricks_ = brick_count;
  constexpr std::size_t kSortVolumeBytes = std::size_t(32) << 20;
  if (params_.sort_min_batch != 0)
    sort_min_ = params_.sort_min_batch;
  else
    sort_min_ = brick_count * kBrickSize * sizeof(float) > kSortVolumeBytes ? brick_count / 4 : SIZE_MAX;
  while (key_bits_ < 63 && (std::uint64_t(brick_count) - 1) >> key_bits_) ++key_bits_;
  base_ = reserve_voxels(data_, stored);
  data_.assign(base_ + stored, 0.0f);
  const std::vector<float> converted = v.type() == VoxelType::f32 ? std::vector<float>() : v.to_float();
  const float* src = v.type() == VoxelType::f32 ? v.data<float>() : converted.data();
  float* dst = data_.data() + base_;
  std::size_t first_bad = v.count(), bad = 0;
  for (std::size_t k = 0, idx = 0; k < dims_.nz; ++k)
    for (std::size_t j = 0; j < dims_.ny; ++j) {
      float* row = dst + offset_[1][j + kPad] + offset_[2][k + kPad];
      for (std::size_t i = 0; i < dims_.nx; ++i, ++idx) {
        const float x = src[idx];
        if (!std::isfinite(x)) {
          if (bad++ == 0) first_bad = idx;
        }
        row[offset_[0][i + kPad]] = x;
      }
    }
  if (bad > 0) {
    const std::size_t i = first_bad % dims_.nx, j = (first_bad / dims_.nx) % dims_.ny,
                      k = first_bad / (dims_.nx * dims_.ny);
    std::ostringstream m;
    m << what << ": voxel (" << i << "," << j << "," << k << ") is " << v.get(first_bad);
    if (std::isfinite(v.get(first_bad))) m << " (outside the float range)";
    m << "; " << bad << " non-finite voxel" << (bad == 1 ? "" : "s")
      << " in all; expected finite values";
    throw InputError(m.str());
  }
}

namespace {
Frame make_frame(const float* data, const std::vector<std::ptrdiff_t> (&off)[3], const Dims& d,
                 const Mat3& inv_dirs, const Vec3& origin, std::size_t sort_min_batch, bool automatic, int key_bits,
                 std::size_t bricks, bool avx2) {
  return Frame{Grid{data,
                    {off[0].data() + kPad, off[1].data() + kPad, off[2].data() + kPad},
                    {double(d.nx) + 1.0, double(d.ny) + 1.0, double(d.nz) + 1.0}},
               inv_dirs, origin, sort_min_batch, automatic, key_bits, bricks, avx2};
}
}  // namespace

double VolumeField::value(const Vec3& x) const {
  double f;
  value_batch(&x, 1, &f);
  return f;
}

double VolumeField::value_gradient(const Vec3& x, Vec3& grad) const {
  double f;
  value_gradient_batch(&x, 1, &f, &grad);
  return f;
}

double VolumeField::evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const {
  double f;
  evaluate_batch(&x, 1, &f, &grad, &hess);
  return f;
}

void VolumeField::value_batch(const Vec3* x, std::size_t n, double* f) const {
  const Frame fr =
      make_frame(data_.data() + base_, offset_, dims_, inv_dirs_, geom_.origin, sort_min_,
                 params_.sort_min_batch == 0, key_bits_, bricks_, avx2_);
  dispatch<0>(params_, avx2_, fr, x, n, f, nullptr, nullptr);
}

void VolumeField::value_gradient_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad) const {
  const Frame fr =
      make_frame(data_.data() + base_, offset_, dims_, inv_dirs_, geom_.origin, sort_min_,
                 params_.sort_min_batch == 0, key_bits_, bricks_, avx2_);
  dispatch<1>(params_, avx2_, fr, x, n, f, grad, nullptr);
}

void VolumeField::evaluate_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) const {
  const Frame fr =
      make_frame(data_.data() + base_, offset_, dims_, inv_dirs_, geom_.origin, sort_min_,
                 params_.sort_min_batch == 0, key_bits_, bricks_, avx2_);
  dispatch<2>(params_, avx2_, fr, x, n, f, grad, hess);
}

std::shared_ptr<const ValueBounds> VolumeField::value_bounds(int block) const {
  if (block < 1) throw UsageError("VolumeField::value_bounds: block must be >= 1, got " + std::to_string(block));
  int nb[3];
  for (int a = 0; a < 3; ++a) nb[a] = (int(dims_[a]) + block - 1) / block;
  const std::size_t nblocks = std::size_t(nb[0]) * std::size_t(nb[1]) * std::size_t(nb[2]);
  // Σ|w| of the value kernel over the 4³ taps (see the header).
  const double wsum = params_.value_kernel == KernelType::catmull_rom ? 1.25 * 1.25 * 1.25 : 1.0;
  const int m = block + 3;  // samples per axis: the cells' taps reach i-1 .. i+2
  // Centred sample positions -c .. c and Σ p² of one axis (the design is a
  // full grid, so the least-squares slopes separate by axis).
  const double c = 0.5 * (m - 1);
  double spp = 0;
  for (int q = 0; q < m; ++q) spp += (q - c) * (q - c);
  const double count = double(m) * m * m;
  auto fill = [this, block, m, c, spp, count, wsum, nbx = nb[0], nby = nb[1]](std::size_t b, float& fl,
                                                                                float& fh) {
    const float* data = data_.data() + base_;
    const int bx = int(b % std::size_t(nbx)), by = int(b / std::size_t(nbx) % std::size_t(nby)),
              bz = int(b / (std::size_t(nbx) * std::size_t(nby)));
    const int b0[3] = {bx * block - 1, by * block - 1, bz * block - 1};
    // Each axis' sample offsets, clamped like the field's offset tables
    // (which replicate the border).
    std::ptrdiff_t off[3][16];
    std::vector<std::ptrdiff_t> big[3];
    std::ptrdiff_t* o[3];
    for (int a = 0; a < 3; ++a) {
      if (m > 16) {
        big[a].resize(std::size_t(m));
        o[a] = big[a].data();
      } else {
        o[a] = off[a];
      }
      for (int q = 0; q < m; ++q) {
        const Index i = std::min<Index>(std::max<Index>(b0[a] + q, 0), Index(dims_[a]) - 1);
        o[a][q] = offset_[a][std::size_t(i + kPad)];
      }
    }
    double sum = 0, sx = 0, sy = 0, sz = 0, ymax = 0;
    for (int qz = 0; qz < m; ++qz)
      for (int qy = 0; qy < m; ++qy)
        for (int qx = 0; qx < m; ++qx) {
          const double v = data[o[0][qx] + o[1][qy] + o[2][qz]];
          sum += v;
          sx += (qx - c) * v;
          sy += (qy - c) * v;
          sz += (qz - c) * v;
          ymax = std::max(ymax, std::fabs(v));
        }
    const double mean = sum / count, gx = sx / (spp * m * m), gy = sy / (spp * m * m), gz = sz / (spp * m * m);
    double e = 0;
    for (int qz = 0; qz < m; ++qz)
      for (int qy = 0; qy < m; ++qy)
        for (int qx = 0; qx < m; ++qx) {
          const double v = data[o[0][qx] + o[1][qy] + o[2][qz]];
          e = std::max(e, std::fabs(v - (mean + gx * (qx - c) + gy * (qy - c) + gz * (qz - c))));
        }
    // L over the block's cells (index offsets 1 .. block+1 from b0, i.e.
    // -block/2 .. block/2 around the centre), plus the residual carried by
    // the weights, plus a margin for the rounding of both the evaluation and
    // these sums.
    const double reach = 0.5 * block * (std::fabs(gx) + std::fabs(gy) + std::fabs(gz));
    const double margin = 1e-9 * (ymax + 1.0);
    const double lo = mean - reach - wsum * e - margin, hi = mean + reach + wsum * e + margin;
    fl = float(lo);
    fh = float(hi);
    if (double(fl) > lo) fl = std::nextafter(fl, -std::numeric_limits<float>::infinity());
    if (double(fh) < hi) fh = std::nextafter(fh, std::numeric_limits<float>::infinity());
  };
  auto r = std::make_shared<ValueBounds>(nblocks, fill);
  r->to_index = inv_dirs_;
  r->origin = geom_.origin;
  r->block = block;
  for (int a = 0; a < 3; ++a) {
    r->n[a] = int(dims_[a]);
    r->nb[a] = nb[a];
  }
  return r;
}

Box VolumeField::domain() const {
  Box b;
  for (int c = 0; c < 8; ++c) {
    const Vec3 ijk((c & 1) ? dims_.nx - 1.0 : 0.0, (c & 2) ? dims_.ny - 1.0 : 0.0,
                   (c & 4) ? dims_.nz - 1.0 : 0.0);
    b.extend(geom_.index_to_world(ijk));
  }
  return b;
}

double VolumeField::resolution() const {
  return std::fmin(geom_.spacing(0), std::fmin(geom_.spacing(1), geom_.spacing(2)));
}

std::string VolumeField::describe() const {
  std::ostringstream s;
  s << "volume ";
  if (!name_.empty())
    s << name_;
  else
    s << dims_.nx << "x" << dims_.ny << "x" << dims_.nz;
  s << " " << kernel_name(params_.value_kernel);
  if (params_.deriv_kernel != params_.value_kernel) s << "/" << kernel_name(params_.deriv_kernel);
  return s.str();
}

}  // namespace pm
