#include "pm/sample/engine.h"

#include "pm/base/cpu.h"
#if PM_AVX2_COPIES
#include <immintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <unordered_map>

namespace pm {

using namespace engine_constants;

namespace {

// The pair loop's scalar arithmetic, the reference of the AVX2 copy.
void pair_terms_scalar(ParticleEnergy en, std::size_t n, const double* d2, const double* al, const double* w,
                       double* ew, double* fs) {
  for (std::size_t s = 0; s < n; ++s) {
    const double dist = std::sqrt(d2[s]);
    double de = 0;
    ew[s] = w[s] * particle_pair_energy(en, al[s] * dist + kEpsR, de);
    if (fs) fs[s] = dist > 0 ? w[s] * de * al[s] / dist : 0.0;
  }
}

#if PM_AVX2_COPIES
// pair_terms_scalar for the cotangent (particle_pair_energy and cot_fast),
// lane by lane: every operation is the scalar one (IEEE add, mul, div,
// sqrt; no FMA in this target) in the scalar order, so every lane's bits
// equal the scalar result. Four pairs per vector, G vectors per round as
// independent chains; a partial last vector is loaded masked and stored
// whole (the outputs have room for n rounded up to four).
template <bool Masked>
__attribute__((target("avx2"), always_inline)) inline __m256d load4(const double* p, __m256i mask) {
  return Masked ? _mm256_maskload_pd(p, mask) : _mm256_loadu_pd(p);
}
template <int G, bool Masked>
__attribute__((target("avx2"), always_inline)) inline void cotangent_round(const double* d2, const double* al,
                                                                          const double* w, double* ew, double* fs,
                                                                          __m256i mask) {
  constexpr double kHalfPi = 1.5707963267948966;
  const __m256d half_pi = _mm256_set1_pd(kHalfPi), one = _mm256_set1_pd(1.0);
  __m256d d[G], a[G], u[G], g[G], in[G];
  for (int v = 0; v < G; ++v) {
    // Idle lanes read d2 = 1 (no 0/0 below).
    __m256d dd = load4<Masked>(d2 + 4 * v, mask);
    if (Masked) dd = _mm256_blendv_pd(_mm256_set1_pd(1.0), dd, _mm256_castsi256_pd(mask));
    d[v] = _mm256_sqrt_pd(dd);
    const __m256d r = _mm256_add_pd(_mm256_mul_pd(load4<Masked>(al + 4 * v, mask), d[v]), _mm256_set1_pd(kEpsR));
    // E and dE/dr are 0 where !(r < 1), as in particle_pair_energy (NaN stays NaN).
    in[v] = _mm256_cmp_pd(r, one, _CMP_NGE_UQ);
    a[v] = _mm256_mul_pd(half_pi, r);
    u[v] = _mm256_sub_pd(_mm256_mul_pd(_mm256_mul_pd(a[v], a[v]), _mm256_set1_pd(kCotU)), one);
    g[v] = _mm256_set1_pd(kCotCoefficients[11]);
  }
  for (int k = 10; k >= 0; --k)
    for (int v = 0; v < G; ++v)
      g[v] = _mm256_add_pd(_mm256_mul_pd(g[v], u[v]), _mm256_set1_pd(kCotCoefficients[k]));
  for (int v = 0; v < G; ++v) {
    const __m256d ct = _mm256_sub_pd(_mm256_div_pd(one, a[v]), _mm256_mul_pd(a[v], g[v]));
    const __m256d wv = load4<Masked>(w + 4 * v, mask);
    const __m256d e = _mm256_and_pd(in[v], _mm256_sub_pd(_mm256_add_pd(ct, a[v]), half_pi));
    _mm256_storeu_pd(ew + 4 * v, _mm256_mul_pd(wv, e));
    if (fs) {
      const __m256d de = _mm256_and_pd(in[v], _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(-kHalfPi), ct), ct));
      const __m256d f = _mm256_div_pd(_mm256_mul_pd(_mm256_mul_pd(wv, de), load4<Masked>(al + 4 * v, mask)), d[v]);
      _mm256_storeu_pd(fs + 4 * v, _mm256_and_pd(_mm256_cmp_pd(d[v], _mm256_setzero_pd(), _CMP_GT_OQ), f));
    }
  }
}

__attribute__((target("avx2"))) void cotangent_terms_avx2(std::size_t n, const double* d2, const double* al,
                                                         const double* w, double* ew, double* fs) {
  const __m256i all = _mm256_set1_epi64x(-1);
  std::size_t s = 0;
  for (; s + 8 <= n; s += 8) cotangent_round<2, false>(d2 + s, al + s, w + s, ew + s, fs ? fs + s : nullptr, all);
  if (s + 4 <= n) {
    cotangent_round<1, false>(d2 + s, al + s, w + s, ew + s, fs ? fs + s : nullptr, all);
    s += 4;
  }
  if (s == n) return;
  const long m = long(n - s);
  const __m256i mask = _mm256_cmpgt_epi64(_mm256_set1_epi64x(m), _mm256_setr_epi64x(0, 1, 2, 3));
  cotangent_round<1, true>(d2 + s, al + s, w + s, ew + s, fs ? fs + s : nullptr, mask);
}

#endif

}  // namespace

void particle_pair_terms(ParticleEnergy en, std::size_t n, const double* d2, const double* al, const double* w,
                         double* ew, double* fs) {
#if PM_AVX2_COPIES
  if (en == ParticleEnergy::cotangent && cpu_has_avx2()) {
    cotangent_terms_avx2(n, d2, al, w, ew, fs);
    return;
  }
#endif
  pair_terms_scalar(en, n, d2, al, w, ew, fs);
}

double engine_beta() {
  static const double beta = 0.5 / std::cos(kPi / 6);
  return beta;
}

std::uint64_t mix64(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

double counter_uniform(std::uint64_t seed, std::uint64_t id, std::uint64_t iter, std::uint64_t stream) {
  std::uint64_t h = mix64(seed ^ 0x5851F42D4C957F2Dull);
  h = mix64(h ^ id);
  h = mix64(h ^ (iter * 0xD1B54A32D192ED03ull));
  h = mix64(h ^ (stream * 0x8CB92BA72F3D8DD7ull));
  return double(h >> 11) * 0x1.0p-53;
}

void tangent_basis(const Vec3& n, Vec3& t1, Vec3& t2) {
  const Vec3 a = std::fabs(n.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  t1 = normalized(cross(n, a));
  t2 = cross(n, t1);
}

Vec3 tangent_offset(const Vec3& n, double angle, double dist) {
  Vec3 t1, t2;
  tangent_basis(n, t1, t2);
  return (t1 * std::cos(angle) + t2 * std::sin(angle)) * dist;
}

int quad_children(const Vec3& n, double theta, double dist, Vec3* out) {
  Vec3 t1, t2;
  tangent_basis(n, t1, t2);
  const Vec3 a = (t1 * std::cos(theta) + t2 * std::sin(theta)) * dist;
  const Vec3 b = (t2 * std::cos(theta) - t1 * std::sin(theta)) * dist;
  out[0] = a + b;
  out[1] = b - a;
  out[2] = -a - b;
  out[3] = a - b;
  return 4;
}

std::string engine_fmt(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}
std::string engine_fmt(const Vec3& v) {
  return "(" + engine_fmt(v.x) + ", " + engine_fmt(v.y) + ", " + engine_fmt(v.z) + ")";
}

const char* project_failure_name(ProjectFailure f) {
  switch (f) {
    case ProjectFailure::none: return "none";
    case ProjectFailure::non_finite: return "the field is not finite at an iterate";
    case ProjectFailure::flat: return "the gradient vanishes (singular system)";
    case ProjectFailure::left_domain: return "the projection left the domain";
    case ProjectFailure::no_convergence: return "the projection did not converge";
    case ProjectFailure::not_dominant: return "another material is above the cell's";
    case ProjectFailure::outside_sizing: return "outside the sizing field's box";
    case ProjectFailure::count_: break;
  }
  return "unknown";
}

Json engine_stats_json(const EngineStats& s) {
  Json fails = Json::object();
  for (int k = 1; k < int(ProjectFailure::count_); ++k)
    if (s.failures_by_reason[k]) fails[project_failure_name(ProjectFailure(k))] = s.failures_by_reason[k];
  Json j = {{"updates", s.updates},
            {"trials", s.trials},
            {"rejected_trials", s.rejected},
            {"settled_skips", s.settled_skips},
            {"field_evaluations", s.field_evaluations},
            {"list_builds", s.list_builds},
            {"regathers", s.regathers},
            {"updates_per_second", s.seconds_relax > 0 ? double(s.updates) / s.seconds_relax : 0.0},
            {"place_failures", s.place_failures},
            {"trial_failures", s.trial_failures},
            {"failures_by_reason", fails},
            {"stuck_particles", s.stuck}};
  if (!s.first_failure.empty()) j["first_stuck"] = s.first_failure;
  return j;
}

std::string engine_failure_summary(const EngineStats& s) {
  if (s.stuck == 0) return {};
  return std::to_string(s.stuck) + " particle update(s) could not project any trial move and left the particle "
         "in place; first: " + s.first_failure;
}

std::vector<std::size_t> thin_points(const std::vector<Vec3>& x, const std::vector<double>& radius,
                                     const std::vector<std::int32_t>& group) {
  // Spatial hash of cubes of the largest radius (large primes mix the indices).
  constexpr std::uint64_t kHashX = 73856093ull, kHashY = 19349663ull, kHashZ = 83492791ull;
  std::vector<std::size_t> kept;
  if (x.empty()) return kept;
  double rmax = 0;
  for (double r : radius) rmax = std::max(rmax, r);
  const double w = std::max(rmax, 1e-12);
  auto key = [&](const Vec3& p, int dx, int dy, int dz) {
    const std::int64_t ix = std::int64_t(std::floor(p.x / w)) + dx, iy = std::int64_t(std::floor(p.y / w)) + dy,
                       iz = std::int64_t(std::floor(p.z / w)) + dz;
    return mix64(std::uint64_t(ix) * kHashX ^ mix64(std::uint64_t(iy) * kHashY ^ mix64(std::uint64_t(iz) * kHashZ)));
  };
  std::unordered_multimap<std::uint64_t, std::size_t> grid;
  for (std::size_t i = 0; i < x.size(); ++i) {
    bool close = false;
    for (int dz = -1; dz <= 1 && !close; ++dz)
      for (int dy = -1; dy <= 1 && !close; ++dy)
        for (int dx = -1; dx <= 1 && !close; ++dx) {
          auto range = grid.equal_range(key(x[i], dx, dy, dz));
          for (auto it = range.first; it != range.second && !close; ++it)
            close = (group.empty() || group[it->second] == group[i]) && norm2(x[it->second] - x[i]) < radius[i] * radius[i];
        }
    if (close) continue;
    grid.emplace(key(x[i], 0, 0, 0), i);
    kept.push_back(i);
  }
  return kept;
}

void add_update_counters(EngineStats& into, const EngineStats& from) {
  into.updates += from.updates;
  into.trials += from.trials;
  into.rejected += from.rejected;
  into.settled_skips += from.settled_skips;
  into.regathers += from.regathers;
  into.field_evaluations += from.field_evaluations;
  into.place_failures += from.place_failures;
  into.trial_failures += from.trial_failures;
  into.stuck += from.stuck;
  for (int k = 0; k < int(ProjectFailure::count_); ++k) into.failures_by_reason[k] += from.failures_by_reason[k];
}

void set_quad_types(EngineParams& p) {
  p.types = 2;
  for (int a = 0; a < kMaxTypes; ++a)
    for (int b = 0; b < kMaxTypes; ++b) p.type_scale[a][b] = a == b ? std::sqrt(2.0) : 1.0;
  p.alternate_types = true;
  p.ideal_neighbours = 8;
  p.recolour_sweeps = engine_constants::kQuadRecolourSweeps;
}

double particle_ideal_energy(ParticleEnergy e) {
  double d = 0;
  return 6.0 * particle_pair_energy(e, engine_beta(), d);
}

// --- bins ----------------------------------------------------------------------

namespace {
// The box of the particles' (finite) positions, without Box::extend's
// NaN-tolerant fmin/fmax (a library call per coordinate; the bins are built
// before every sweep and the fine grid before every colour).
Box points_box(const std::vector<Vec3>& x) {
  Box bb;
  for (const Vec3& p : x)
    for (int a = 0; a < 3; ++a) {
      bb.lo[a] = p[a] < bb.lo[a] ? p[a] : bb.lo[a];
      bb.hi[a] = p[a] > bb.hi[a] ? p[a] : bb.hi[a];
    }
  return bb;
}
}  // namespace

void SampleBins::build(const std::vector<Vec3>& x, double w, const std::vector<char>& active, int sub) {
  const std::size_t n = x.size();
  const Box bb = points_box(x);
  // Keep the grid's index space reasonable (wider bins are always correct).
  const Vec3 ext = n ? bb.size() : Vec3{};
  const double longest = std::max({ext.x, ext.y, ext.z, 0.0});
  w = std::max({w, longest / double(1 << 20), 1e-300});
  w_ = w;
  lo_ = (n ? bb.lo : Vec3{}) - Vec3{w, w, w};
  nx_ = std::uint64_t(std::floor(ext.x / w)) + 3;
  ny_ = std::uint64_t(std::floor(ext.y / w)) + 3;
  nz_ = std::uint64_t(std::floor(ext.z / w)) + 3;
  sub_ = std::max(1, sub);
  // Keys are (bin, sub-cell) in 64 bits: a grid stretched by a far outlier
  // (up to 2^20 bins an axis) keeps whole bins.
  if (double(nx_) * double(ny_) * double(nz_) * double(sub_) * sub_ * sub_ > 0x1p62) sub_ = 1;
  const std::uint64_t S = std::uint64_t(sub_), S3 = S * S * S;
  auto sub_of = [&](double t, std::uint64_t i) {
    const double f = (t - double(i)) * double(S);
    return f <= 0 ? std::uint64_t(0) : std::min(std::uint64_t(f), S - 1);
  };

  keys_.resize(n);
  keys_tmp_.resize(n);
  order_.resize(n);
  order_tmp_.resize(n);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const Vec3 t = (x[i] - lo_) / w;
      const std::uint64_t ix = std::min<std::uint64_t>(std::uint64_t(std::max(0.0, t.x)), nx_ - 2);
      const std::uint64_t iy = std::min<std::uint64_t>(std::uint64_t(std::max(0.0, t.y)), ny_ - 2);
      const std::uint64_t iz = std::min<std::uint64_t>(std::uint64_t(std::max(0.0, t.z)), nz_ - 2);
      const std::uint64_t sc = sub_of(t.x, ix) + S * (sub_of(t.y, iy) + S * sub_of(t.z, iz));
      keys_[i] = (ix + nx_ * (iy + ny_ * iz)) * S3 + sc;
      order_[i] = std::uint32_t(i);
    }
  });
  // LSD radix sort of (key, index): counting sort per 11-bit digit; stable,
  // so points keep their previous relative order within a sub-cell.
  const std::uint64_t total = nx_ * ny_ * nz_ * S3;
  int bits = 1;
  while (bits < 64 && (std::uint64_t(1) << bits) < total) ++bits;
  constexpr int kDigit = 11;
  radix_count_.resize(std::size_t(1) << kDigit);
  for (int shift = 0; shift < bits; shift += kDigit) {
    std::fill(radix_count_.begin(), radix_count_.end(), 0u);
    const std::uint64_t mask = (std::uint64_t(1) << kDigit) - 1;
    for (std::size_t i = 0; i < n; ++i) ++radix_count_[(keys_[i] >> shift) & mask];
    std::uint32_t sum = 0;
    for (auto& c : radix_count_) {
      const std::uint32_t t = c;
      c = sum;
      sum += t;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t slot = radix_count_[(keys_[i] >> shift) & mask]++;
      keys_tmp_[slot] = keys_[i];
      order_tmp_[slot] = order_[i];
    }
    keys_.swap(keys_tmp_);
    order_.swap(order_tmp_);
  }

  // Cells: runs of equal bin keys; per cell, where each sub-cell starts.
  cell_key_.clear();
  cell_start_.clear();
  sub_start_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t bin = keys_[i] / S3;
    if (i == 0 || bin != keys_[i - 1] / S3) {
      if (i > 0) sub_start_.resize(cell_key_.size() * (S3 + 1), std::uint32_t(i));
      cell_key_.push_back(bin);
      cell_start_.push_back(std::uint32_t(i));
    }
    // Sub-cells up to this point's start here (empty ones included).
    const std::size_t base = (cell_key_.size() - 1) * (S3 + 1);
    sub_start_.resize(base + keys_[i] % S3 + 1, std::uint32_t(i));
  }
  cell_start_.push_back(std::uint32_t(n));
  sub_start_.resize(cell_key_.size() * (S3 + 1), std::uint32_t(n));
  const std::size_t nc = cell_key_.size();

  // Open-addressing hash key -> cell index + 1.
  std::size_t hsize = 16;
  while (hsize < 2 * nc) hsize *= 2;
  hash_.assign(hsize, 0u);
  const std::size_t hmask = hsize - 1;
  for (std::size_t c = 0; c < nc; ++c) {
    std::size_t h = mix64(cell_key_[c]) & hmask;
    while (hash_[h]) h = (h + 1) & hmask;
    hash_[h] = std::uint32_t(c + 1);
  }
  cell_nbr_.resize(nc * 27);
  cell_lo_.resize(nc);
  inv_ws_ = double(sub_) / w_;
  colour_start_.assign(kColours + 1, 0u);
  std::vector<std::int8_t> colour(nc, -1);
  for (std::size_t c = 0; c < nc; ++c) {
    const std::uint64_t k = cell_key_[c];
    const std::uint64_t ix = k % nx_, iy = (k / nx_) % ny_, iz = k / (nx_ * ny_);
    cell_lo_[c] = Vec3(lo_.x + double(ix) * w_, lo_.y + double(iy) * w_, lo_.z + double(iz) * w_);
    int m = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          cell_nbr_[c * 27 + std::size_t(m++)] = find((ix + dx) + nx_ * ((iy + dy) + ny_ * (iz + dz)));
    bool any = active.empty();
    for (std::uint32_t i = cell_start_[c]; i < cell_start_[c + 1] && !any; ++i) any = active[order_[i]] != 0;
    if (!any) continue;
    colour[c] = std::int8_t((ix & 1) + 2 * (iy & 1) + 4 * (iz & 1));
    ++colour_start_[std::size_t(colour[c]) + 1];
  }
  for (int c = 0; c < kColours; ++c) colour_start_[std::size_t(c) + 1] += colour_start_[std::size_t(c)];
  colour_cells_.resize(colour_start_[kColours]);
  std::uint32_t fill[kColours];
  for (int c = 0; c < kColours; ++c) fill[c] = colour_start_[std::size_t(c)];
  for (std::size_t c = 0; c < nc; ++c)
    if (colour[c] >= 0) colour_cells_[fill[colour[c]]++] = std::uint32_t(c);
}

void DenseBins::build(const std::vector<Vec3>& x, double w, std::size_t max_cells) {
  const std::size_t n = x.size();
  start_.clear();
  order_.resize(n);
  if (n == 0 || !(w > 0)) return;
  const Box bb = points_box(x);
  const Vec3 ext = bb.size();
  max_cells = std::max<std::size_t>(max_cells, 1);
  for (;;) {
    std::size_t total = 1;
    for (int a = 0; a < 3; ++a) {
      n_[a] = long(std::floor(ext[a] / w)) + 1;
      total *= std::size_t(n_[a]);
    }
    if (total <= max_cells) break;
    w *= std::max(1.01, std::cbrt(double(total) / double(max_cells)));
  }
  w_ = w;
  inv_w_ = 1.0 / w;
  lo_ = bb.lo;
  const std::size_t cells = std::size_t(n_[0]) * std::size_t(n_[1]) * std::size_t(n_[2]);
  // Counting sort by cell: stable, so a cell lists its points by index.
  // The cells in parallel; then start_[c] counts up to the end of cell c,
  // and a backward scatter leaves it at the cell's first slot.
  cell_of_.resize(n);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const Vec3& p = x[i];
      cell_of_[i] = std::uint32_t(std::size_t(clamp_cell(p.x, 0)) +
                                  std::size_t(n_[0]) * (std::size_t(clamp_cell(p.y, 1)) +
                                                        std::size_t(n_[1]) * std::size_t(clamp_cell(p.z, 2))));
    }
  });
  start_.assign(cells + 1, 0u);
  for (std::size_t i = 0; i < n; ++i) ++start_[cell_of_[i]];
  for (std::size_t c = 1; c < cells; ++c) start_[c] += start_[c - 1];
  start_[cells] = std::uint32_t(n);
  for (std::size_t i = n; i-- > 0;) order_[--start_[cell_of_[i]]] = std::uint32_t(i);
}

std::int32_t SampleBins::find(std::uint64_t key) const {
  const std::size_t hmask = hash_.size() - 1;
  std::size_t h = mix64(key) & hmask;
  while (hash_[h]) {
    const std::uint32_t c = hash_[h] - 1;
    if (cell_key_[c] == key) return std::int32_t(c);
    h = (h + 1) & hmask;
  }
  return -1;
}

void SampleBins::axis_masks(std::size_t c, const Vec3& x, double slack, int m[3]) const {
  for (int a = 0; a < 3; ++a) {
    const double c0 = cell_lo_[c][a], c1 = c0 + w_;
    m[a] = (x[a] - slack < c0 ? 1 : 0) | 2 | (x[a] + slack >= c1 ? 4 : 0);
  }
}

bool SampleBins::block_of(const Vec3& x, std::int32_t out[27]) const {
  // The grid spans the points' box grown by one bin, so a point outside it
  // has no point within one bin width. A point in a margin bin (a point at
  // the box's lower corner lands there when (x - lo) / w rounds below 1)
  // takes the block of the bin inside it, which holds the margin bin too.
  if (hash_.empty()) return false;
  const Vec3 t = (x - lo_) / w_;
  if (!(t.x >= 0 && t.y >= 0 && t.z >= 0 && t.x < double(nx_) && t.y < double(ny_) && t.z < double(nz_)))
    return false;
  auto inner = [](double v, std::uint64_t n) { return std::min(std::max(std::uint64_t(v), std::uint64_t(1)), n - 2); };
  if (nx_ < 3 || ny_ < 3 || nz_ < 3) return false;
  const std::uint64_t ix = inner(t.x, nx_), iy = inner(t.y, ny_), iz = inner(t.z, nz_);
  int m = 0;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) out[m++] = find((ix + dx) + nx_ * ((iy + dy) + ny_ * (iz + dz)));
  return true;
}

}  // namespace pm
