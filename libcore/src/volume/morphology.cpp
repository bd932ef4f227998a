#include "pm/volume/morphology.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/base/parallel.h"
#include "pm/volume/labels.h"

namespace pm {

// ---------------------------------------------------------------------------
// Names
// ---------------------------------------------------------------------------

MorphOp parse_morph_op(const std::string& n) {
  if (n == "erode") return MorphOp::erode;
  if (n == "dilate") return MorphOp::dilate;
  if (n == "open") return MorphOp::open;
  if (n == "close") return MorphOp::close;
  throw UsageError("unknown morphology operation \"" + n + "\"; expected erode, dilate, open or close");
}

const char* morph_op_name(MorphOp op) {
  switch (op) {
    case MorphOp::erode: return "erode";
    case MorphOp::dilate: return "dilate";
    case MorphOp::open: return "open";
    case MorphOp::close: return "close";
  }
  return "?";
}

Stencil parse_stencil(const std::string& n) {
  static const std::pair<const char*, Stencil> names[] = {
      {"plus", Stencil::plus}, {"ball", Stencil::ball}, {"cube", Stencil::cube}, {"f1", Stencil::f1},
      {"f2", Stencil::f2},     {"f3", Stencil::f3},     {"f4", Stencil::f4}};
  for (const auto& [s, v] : names)
    if (n == s) return v;
  throw UsageError("unknown stencil \"" + n + "\"; expected plus, ball, cube, f1, f2, f3 or f4");
}

const char* stencil_name(Stencil s) {
  switch (s) {
    case Stencil::plus: return "plus";
    case Stencil::ball: return "ball";
    case Stencil::cube: return "cube";
    case Stencil::f1: return "f1";
    case Stencil::f2: return "f2";
    case Stencil::f3: return "f3";
    case Stencil::f4: return "f4";
  }
  return "?";
}

std::vector<Stencil> stencil_parts(Stencil s) {
  using S = Stencil;
  switch (s) {
    case S::plus: case S::ball: case S::cube: return {s};
    case S::f1: return {S::ball};
    case S::f2: return {S::ball, S::cube};
    case S::f3: return {S::ball, S::plus, S::cube};
    case S::f4: return {S::plus, S::ball, S::cube, S::plus};
  }
  return {s};
}

std::vector<MorphStep> parse_morph_steps(const std::string& spec) {
  std::vector<MorphStep> steps;
  std::string item;
  std::istringstream in(spec);
  while (std::getline(in, item, ',')) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (item.empty()) continue;
    std::vector<std::string> parts;
    std::string part;
    std::istringstream ps(item);
    while (std::getline(ps, part, ':')) parts.push_back(part);
    const std::string expected = "; expected op:stencil[:iterations], e.g. \"close:f4,open:f2\"";
    if (parts.empty() || parts.size() > 3) throw UsageError("morphology step \"" + item + "\" is malformed" + expected);
    MorphStep s;
    s.op = parse_morph_op(parts[0]);
    if (parts.size() >= 2) s.stencil = parse_stencil(parts[1]);
    if (parts.size() == 3) {
      std::size_t pos = 0;
      int n = 0;
      try {
        n = std::stoi(parts[2], &pos);
      } catch (const std::exception&) {
        pos = 0;
      }
      if (pos == 0 || pos != parts[2].size() || n < 1)
        throw UsageError("morphology step \"" + item + "\": iterations \"" + parts[2] +
                         "\" is not an integer >= 1" + expected);
      s.iterations = n;
    }
    steps.push_back(s);
  }
  if (steps.empty()) throw UsageError("morphology sequence \"" + spec + "\" is empty; expected e.g. \"close:f4,open:f2\"");
  return steps;
}

// ---------------------------------------------------------------------------
// Dense binary passes on a padded region
// ---------------------------------------------------------------------------

namespace {

constexpr std::uint16_t kEmpty = 0xFFFF;

/// A 0/1 mask on a box of the (unbounded) voxel lattice whose outermost layer
/// is always 0, so interior voxels have all 26 neighbours without bounds checks.
struct Region {
  long x0 = 0, y0 = 0, z0 = 0;  // lattice position of region voxel (0,0,0)
  std::size_t nx = 0, ny = 0, nz = 0;
  std::vector<std::uint8_t> a;
  std::size_t at(std::size_t i, std::size_t j, std::size_t k) const { return i + nx * (j + ny * k); }
};

// The passes run on the region packed 64 voxels to a word along x (a row
// (j,k) is `nw` words, voxel i at bit i % 64 of word i / 64): one word
// operation does 64 voxels, and the region's traffic is an eighth.
struct BitRows {
  std::size_t ny = 0, nz = 0, nw = 0;
  std::vector<std::uint64_t> w;
  std::uint64_t* row(std::size_t j, std::size_t k) { return w.data() + (j + ny * k) * nw; }
  const std::uint64_t* row(std::size_t j, std::size_t k) const { return w.data() + (j + ny * k) * nw; }
};

// One pass with a basic stencil. rx holds the 3-tap row combination along x;
// the stencils then combine rows: plus = rx(0,0) + a(+-1,0) + a(0,+-1);
// ball = rx(0,0) + rx(+-1,0) + rx(0,+-1) + a(+-1,+-1); cube = rx over 3x3.
// Only interior voxels are written (the region's outermost layer stays 0):
// `valid` masks the bits of x = 1 .. nx - 2. `rows` flags the x rows (j,k)
// holding any voxel; a row whose stencil rows are all empty (dilation) or
// include an empty one (erosion) is 0 without being computed, which makes
// sparse masks and large bounding boxes cheap.
template <bool Dilate>
void basic_pass(BitRows& a, BitRows& rx, BitRows& out, std::vector<std::uint8_t>& rows,
                std::vector<std::uint8_t>& rows_out, const std::vector<std::uint64_t>& valid, Stencil s) {
  const std::size_t ny = a.ny, nz = a.nz, nw = a.nw;
  const std::uint8_t* rw = rows.data();
  auto op = [](std::uint64_t p, std::uint64_t q) -> std::uint64_t { return Dilate ? (p | q) : (p & q); };
  pm::parallel_for(tbb::blocked_range<std::size_t>(1, nz - 1), [&](const tbb::blocked_range<std::size_t>& zr) {
    for (std::size_t k = zr.begin(); k != zr.end(); ++k)
      for (std::size_t j = 1; j + 1 < ny; ++j) {
        std::uint64_t* __restrict o = rx.row(j, k);
        if (!rw[j + ny * k]) {
          std::fill(o, o + nw, std::uint64_t(0));
          continue;
        }
        const std::uint64_t* __restrict c = a.row(j, k);
        for (std::size_t t = 0; t < nw; ++t) {
          const std::uint64_t left = c[t] << 1 | (t > 0 ? c[t - 1] >> 63 : 0);        // bit i holds x = i - 1
          const std::uint64_t right = c[t] >> 1 | (t + 1 < nw ? c[t + 1] << 63 : 0);  // bit i holds x = i + 1
          o[t] = op(op(left, c[t]), right) & valid[t];
        }
      }
  });
  pm::parallel_for(tbb::blocked_range<std::size_t>(1, nz - 1), [&](const tbb::blocked_range<std::size_t>& zr) {
    for (std::size_t k = zr.begin(); k != zr.end(); ++k)
      for (std::size_t j = 1; j + 1 < ny; ++j) {
        std::uint64_t* __restrict o = out.row(j, k);
        // Which neighbour rows the stencil reads: plus/ball the 5 rows of the yz
        // plus (ball also the 4 yz diagonals), cube all 9.
        bool any = false, all = true;
        for (int dk = -1; dk <= 1; ++dk)
          for (int dj = -1; dj <= 1; ++dj) {
            if (s == Stencil::plus && dj != 0 && dk != 0) continue;
            const bool f = rw[(j + dj) + ny * (k + dk)] != 0;
            any |= f;
            all &= f;
          }
        if (Dilate ? !any : !all) {
          std::fill(o, o + nw, std::uint64_t(0));
          rows_out[j + ny * k] = 0;
          continue;
        }
        const std::uint64_t *x0 = rx.row(j, k), *xm = rx.row(j - 1, k), *xp = rx.row(j + 1, k),
                            *xd = rx.row(j, k - 1), *xu = rx.row(j, k + 1);
        std::uint64_t acc = 0;
        switch (s) {
          case Stencil::plus: {
            const std::uint64_t *am = a.row(j - 1, k), *ap = a.row(j + 1, k), *ad = a.row(j, k - 1),
                                *au = a.row(j, k + 1);
            for (std::size_t t = 0; t < nw; ++t) {
              o[t] = op(op(op(x0[t], am[t]), op(ap[t], ad[t])), au[t]) & valid[t];
              acc |= o[t];
            }
            break;
          }
          case Stencil::ball: {
            const std::uint64_t *amd = a.row(j - 1, k - 1), *apd = a.row(j + 1, k - 1), *amu = a.row(j - 1, k + 1),
                                *apu = a.row(j + 1, k + 1);
            for (std::size_t t = 0; t < nw; ++t) {
              const std::uint64_t rws = op(op(op(x0[t], xm[t]), op(xp[t], xd[t])), xu[t]);
              const std::uint64_t diag = op(op(amd[t], apd[t]), op(amu[t], apu[t]));
              o[t] = op(rws, diag) & valid[t];
              acc |= o[t];
            }
            break;
          }
          default: {  // cube
            const std::uint64_t *xmd = rx.row(j - 1, k - 1), *xpd = rx.row(j + 1, k - 1),
                                *xmu = rx.row(j - 1, k + 1), *xpu = rx.row(j + 1, k + 1);
            for (std::size_t t = 0; t < nw; ++t) {
              const std::uint64_t m0 = op(op(xmd[t], xd[t]), xpd[t]);
              const std::uint64_t m1 = op(op(xm[t], x0[t]), xp[t]);
              const std::uint64_t m2 = op(op(xmu[t], xu[t]), xpu[t]);
              o[t] = op(op(m0, m1), m2) & valid[t];
              acc |= o[t];
            }
            break;
          }
        }
        rows_out[j + ny * k] = acc != 0;
      }
  });
  a.w.swap(out.w);
  rows.swap(rows_out);
}

void check_steps(const std::vector<MorphStep>& steps) {
  for (const MorphStep& s : steps)
    if (s.iterations < 1)
      throw UsageError(std::string("morphology: ") + morph_op_name(s.op) + " with " + std::to_string(s.iterations) +
                       " iterations; expected >= 1");
}

/// Number of dilation passes of a sequence: how far material can grow.
std::size_t growth(const std::vector<MorphStep>& steps) {
  std::size_t n = 0;
  for (const MorphStep& s : steps)
    if (s.op != MorphOp::erode) n += stencil_parts(s.stencil).size() * std::size_t(s.iterations);
  return n;
}

void run_steps(Region& r, const std::vector<MorphStep>& steps) {
  const std::size_t nx = r.nx, ny = r.ny, nz = r.nz, nw = (nx + 63) / 64;
  BitRows a{ny, nz, nw, std::vector<std::uint64_t>(ny * nz * nw, 0)};
  BitRows rx = a, out = a;
  std::vector<std::uint8_t> rows(ny * nz, 0), rows_out(ny * nz, 0);
  // Bits of x = 1 .. nx - 2 (the passes write only those).
  std::vector<std::uint64_t> valid(nw, 0);
  for (std::size_t i = 1; i + 1 < nx; ++i) valid[i / 64] |= std::uint64_t(1) << (i % 64);
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    for (std::size_t j = 0; j < ny; ++j) {
      const std::uint8_t* src = r.a.data() + r.at(0, j, k);
      std::uint64_t* dst = a.row(j, k);
      std::uint64_t any = 0;
      for (std::size_t t = 0; t < nw; ++t) {
        std::uint64_t w = 0;
        const std::size_t i0 = 64 * t, n = std::min<std::size_t>(64, nx - i0);
        for (std::size_t b = 0; b < n; ++b) w |= std::uint64_t(src[i0 + b] != 0) << b;
        dst[t] = w;
        any |= w;
      }
      rows[j + ny * k] = any != 0;
    }
  });
  auto passes = [&](bool dilate, Stencil s, int iterations) {
    for (int it = 0; it < iterations; ++it)
      for (Stencil part : stencil_parts(s)) {
        if (dilate)
          basic_pass<true>(a, rx, out, rows, rows_out, valid, part);
        else
          basic_pass<false>(a, rx, out, rows, rows_out, valid, part);
      }
  };
  for (const MorphStep& s : steps) {
    switch (s.op) {
      case MorphOp::erode: passes(false, s.stencil, s.iterations); break;
      case MorphOp::dilate: passes(true, s.stencil, s.iterations); break;
      case MorphOp::open:
        passes(false, s.stencil, s.iterations);
        passes(true, s.stencil, s.iterations);
        break;
      case MorphOp::close:
        passes(true, s.stencil, s.iterations);
        passes(false, s.stencil, s.iterations);
        break;
    }
  }
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    for (std::size_t j = 0; j < ny; ++j) {
      std::uint8_t* dst = r.a.data() + r.at(0, j, k);
      const std::uint64_t* src = a.row(j, k);
      for (std::size_t i = 0; i < nx; ++i) dst[i] = std::uint8_t((src[i / 64] >> (i % 64)) & 1);
    }
  });
}

struct BBox {
  long lo[3] = {0, 0, 0}, hi[3] = {-1, -1, -1};
  bool empty() const { return hi[0] < lo[0]; }
  void add(long i, long j, long k) {
    if (empty()) {
      lo[0] = hi[0] = i; lo[1] = hi[1] = j; lo[2] = hi[2] = k;
      return;
    }
    lo[0] = std::min(lo[0], i); hi[0] = std::max(hi[0], i);
    lo[1] = std::min(lo[1], j); hi[1] = std::max(hi[1], j);
    lo[2] = std::min(lo[2], k); hi[2] = std::max(hi[2], k);
  }
};

/// Region covering `b` plus `pad` voxels of margin on every side (zero-filled).
Region make_region(const BBox& b, std::size_t pad) {
  Region r;
  r.x0 = b.lo[0] - long(pad);
  r.y0 = b.lo[1] - long(pad);
  r.z0 = b.lo[2] - long(pad);
  r.nx = std::size_t(b.hi[0] - b.lo[0] + 1) + 2 * pad;
  r.ny = std::size_t(b.hi[1] - b.lo[1] + 1) + 2 * pad;
  r.nz = std::size_t(b.hi[2] - b.lo[2] + 1) + 2 * pad;
  r.a.assign(r.nx * r.ny * r.nz, 0);
  return r;
}

/// Calls f(region index, volume index, n) for every x run of n region voxels
/// inside the volume (region and volume indices advance together along a
/// run), parallel over z.
template <class F>
void for_region_rows_in_volume(const Region& r, const Dims& d, F&& f) {
  const long zlo = std::max(0L, r.z0), zhi = std::min(long(d.nz), r.z0 + long(r.nz));
  const long ylo = std::max(0L, r.y0), yhi = std::min(long(d.ny), r.y0 + long(r.ny));
  const long xlo = std::max(0L, r.x0), xhi = std::min(long(d.nx), r.x0 + long(r.nx));
  if (zlo >= zhi || ylo >= yhi || xlo >= xhi) return;
  const std::size_t n = std::size_t(xhi - xlo);
  pm::parallel_for(tbb::blocked_range<long>(zlo, zhi), [&](const tbb::blocked_range<long>& zr) {
    for (long k = zr.begin(); k != zr.end(); ++k)
      for (long j = ylo; j < yhi; ++j)
        f(r.at(std::size_t(xlo - r.x0), std::size_t(j - r.y0), std::size_t(k - r.z0)),
          std::size_t(xlo) + d.nx * (std::size_t(j) + d.ny * std::size_t(k)), n);
  });
}

/// Calls f(region index, volume index) for every region voxel inside the volume, parallel over z.
template <class F>
void for_region_in_volume(const Region& r, const Dims& d, F&& f) {
  for_region_rows_in_volume(r, d, [&](std::size_t ri, std::size_t vi, std::size_t n) {
    for (std::size_t t = 0; t < n; ++t) f(ri + t, vi + t);
  });
}

// ---------------------------------------------------------------------------
// Label maps as dense indices into a sorted label table
// ---------------------------------------------------------------------------

struct Indexed {
  Dims dims;
  std::vector<std::int64_t> values;  // sorted distinct labels
  std::vector<std::uint16_t> idx;    // per voxel: index into values, or kEmpty
};

Indexed index_labels(const Volume& v, const std::string& what) {
  require_labels(v, what);
  Indexed x;
  x.dims = v.dims();
  const std::size_t n = v.count();
  x.idx.resize(n);
  std::unordered_map<std::int64_t, std::uint16_t> ids;
  std::int64_t last = 0;
  std::uint16_t last_id = kEmpty;
  visit_voxel_type(v.type(), [&](auto tag) {
    using T = decltype(tag);
    const T* p = v.data<T>();
    for (std::size_t i = 0; i < n; ++i) {
      const auto val = std::int64_t(static_cast<double>(p[i]));
      if (last_id == kEmpty || val != last) {
        auto it = ids.find(val);
        if (it == ids.end()) {
          if (x.values.size() >= kEmpty)
            throw InputError(what + ": more than " + std::to_string(kEmpty - 1) +
                             " distinct labels; expected a label map");
          it = ids.emplace(val, std::uint16_t(x.values.size())).first;
          x.values.push_back(val);
        }
        last = val;
        last_id = it->second;
      }
      x.idx[i] = last_id;
    }
    return 0;
  });
  // Renumber so that index order is label order (ties -> smallest label == smallest index).
  std::vector<std::int64_t> sorted = x.values;
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::uint16_t> remap(x.values.size());
  for (std::size_t a = 0; a < x.values.size(); ++a)
    remap[a] = std::uint16_t(std::lower_bound(sorted.begin(), sorted.end(), x.values[a]) - sorted.begin());
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) x.idx[i] = remap[x.idx[i]];
  });
  x.values = std::move(sorted);
  return x;
}

Volume write_labels(const Indexed& x, VoxelType type, const Geometry& g, std::int64_t empty_value) {
  Volume out(type, x.dims, g);
  // Each label's voxel value as set() stores it, then copied (no conversion per voxel).
  Volume table(type, Dims{x.values.size() + 1, 1, 1});
  for (std::size_t a = 0; a < x.values.size(); ++a) table.set(a, double(x.values[a]));
  table.set(x.values.size(), double(empty_value));
  visit_voxel_type(type, [&](auto tag) {
    using T = decltype(tag);
    const T* t = table.data<T>();
    T* o = out.data<T>();
    const std::size_t empty = x.values.size();
    pm::parallel_for(tbb::blocked_range<std::size_t>(0, x.idx.size()), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) o[i] = t[x.idx[i] == kEmpty ? empty : x.idx[i]];
    });
    return 0;
  });
  return out;
}

// Voxels per label index (of nl; empty voxels not counted), by slabs in parallel.
std::vector<std::size_t> index_counts(const std::vector<std::uint16_t>& idx, std::size_t nl) {
  const std::size_t n = idx.size();
  constexpr std::size_t kChunk = std::size_t(1) << 20;
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  std::vector<std::size_t> per(chunks * nl, 0);
  pm::parallel_for(std::size_t(0), chunks, [&](std::size_t ch) {
    std::size_t* c = per.data() + ch * nl;
    // By runs of one label (label maps are mostly long runs): one addition
    // per run instead of a chain of increments of the same counter.
    for (std::size_t i = ch * kChunk, e = std::min(n, i + kChunk); i < e;) {
      const std::uint16_t v = idx[i];
      std::size_t j = i + 1;
      while (j < e && idx[j] == v) ++j;
      if (v != kEmpty) c[v] += j - i;
      i = j;
    }
  });
  std::vector<std::size_t> c(nl, 0);
  for (std::size_t ch = 0; ch < chunks; ++ch)
    for (std::size_t a = 0; a < nl; ++a) c[a] += per[ch * nl + a];
  return c;
}
std::vector<std::size_t> index_counts(const Indexed& x) { return index_counts(x.idx, x.values.size()); }

std::map<std::int64_t, std::size_t> counts_of(const Indexed& x) {
  const std::vector<std::size_t> c = index_counts(x);
  std::map<std::int64_t, std::size_t> m;
  for (std::size_t a = 0; a < c.size(); ++a)
    if (c[a]) m[x.values[a]] = c[a];
  return m;
}

/// Simultaneous voting rounds until no voxel is kEmpty. Returns the number of rounds.
std::size_t vote_indices(Indexed& x, const std::string& what) {
  const Dims d = x.dims;
  std::vector<std::size_t> todo;
  for (std::size_t i = 0; i < x.idx.size(); ++i)
    if (x.idx[i] == kEmpty) todo.push_back(i);
  if (todo.empty()) return 0;
  if (todo.size() == x.idx.size())
    throw InputError(what + ": every voxel is empty; voting needs at least one labelled voxel");
  std::vector<std::uint16_t> decision;
  std::size_t rounds = 0;
  while (!todo.empty()) {
    ++rounds;
    decision.assign(todo.size(), kEmpty);
    pm::parallel_for(tbb::blocked_range<std::size_t>(0, todo.size()), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t t = r.begin(); t != r.end(); ++t) {
        const std::size_t v = todo[t];
        const std::size_t i = v % d.nx, j = (v / d.nx) % d.ny, k = v / (d.nx * d.ny);
        std::array<std::uint16_t, 6> nb;
        int n = 0;
        auto take = [&](std::size_t u) {
          if (x.idx[u] != kEmpty) nb[n++] = x.idx[u];
        };
        if (i > 0) take(v - 1);
        if (i + 1 < d.nx) take(v + 1);
        if (j > 0) take(v - d.nx);
        if (j + 1 < d.ny) take(v + d.nx);
        if (k > 0) take(v - d.nx * d.ny);
        if (k + 1 < d.nz) take(v + d.nx * d.ny);
        if (n == 0) continue;
        for (int a = 1; a < n; ++a)  // insertion sort of <= 6 values
          for (int b = a; b > 0 && nb[b - 1] > nb[b]; --b) std::swap(nb[b - 1], nb[b]);
        std::uint16_t best = nb[0];
        int best_count = 0;
        for (int a = 0; a < n;) {
          int b = a;
          while (b < n && nb[b] == nb[a]) ++b;
          if (b - a > best_count) {  // strictly more: ties keep the smaller label
            best_count = b - a;
            best = nb[a];
          }
          a = b;
        }
        decision[t] = best;
      }
    });
    std::vector<std::size_t> next;
    for (std::size_t t = 0; t < todo.size(); ++t) {
      if (decision[t] == kEmpty)
        next.push_back(todo[t]);
      else
        x.idx[todo[t]] = decision[t];
    }
    todo.swap(next);
  }
  return rounds;
}

Geometry downsampled_geometry(const Geometry& g, int k) {
  Geometry o = g;
  const double h = 0.5 * double(k - 1);
  o.origin = g.index_to_world(Vec3(h, h, h));
  o.directions = g.directions * double(k);
  return o;
}

Dims downsampled_dims(const Dims& d, int k) {
  const std::size_t kk = std::size_t(k);
  return Dims{(d.nx + kk - 1) / kk, (d.ny + kk - 1) / kk, (d.nz + kk - 1) / kk};
}

/// Calls f(output index, list of input indices of its block) in parallel over output z.
template <class F>
void for_blocks(const Dims& in, const Dims& out, int k, F&& f) {
  const std::size_t kk = std::size_t(k);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, out.nz), [&](const tbb::blocked_range<std::size_t>& zr) {
    std::vector<std::size_t> block;
    block.reserve(kk * kk * kk);
    for (std::size_t oz = zr.begin(); oz != zr.end(); ++oz)
      for (std::size_t oy = 0; oy < out.ny; ++oy)
        for (std::size_t ox = 0; ox < out.nx; ++ox) {
          block.clear();
          for (std::size_t z = oz * kk; z < std::min(in.nz, oz * kk + kk); ++z)
            for (std::size_t y = oy * kk; y < std::min(in.ny, oy * kk + kk); ++y)
              for (std::size_t x = ox * kk; x < std::min(in.nx, ox * kk + kk); ++x)
                block.push_back(x + in.nx * (y + in.ny * z));
          f(ox + out.nx * (oy + out.ny * oz), block);
        }
  });
}

// The most frequent label of each k^3 block (ties: the smallest index;
// empty voxels do not vote). Most blocks hold one label: they skip the sort.
Indexed downsample_indices(const Indexed& x, int k) {
  Indexed o;
  o.values = x.values;
  o.dims = downsampled_dims(x.dims, k);
  o.idx.assign(o.dims.count(), kEmpty);
  for_blocks(x.dims, o.dims, k, [&](std::size_t oi, const std::vector<std::size_t>& block) {
    thread_local std::vector<std::uint16_t> vals;  // no allocation per output voxel
    vals.clear();
    for (std::size_t b : block)
      if (x.idx[b] != kEmpty) vals.push_back(x.idx[b]);
    if (vals.empty()) return;
    std::uint16_t best = vals[0];
    if (std::find_if(vals.begin(), vals.end(), [&](std::uint16_t v) { return v != best; }) != vals.end()) {
      std::sort(vals.begin(), vals.end());
      best = vals[0];
      std::size_t best_count = 0;
      for (std::size_t a = 0; a < vals.size();) {
        std::size_t b = a;
        while (b < vals.size() && vals[b] == vals[a]) ++b;
        if (b - a > best_count) {
          best_count = b - a;
          best = vals[a];
        }
        a = b;
      }
    }
    o.idx[oi] = best;
  });
  return o;
}

// Removes (sets empty) every 6-connected component of one label with fewer
// than `min_voxels` voxels, except a label's largest component when all of its
// components are that small (listed in `kept`); returns {components removed,
// voxels removed}.
std::pair<std::size_t, std::size_t> remove_small_components(Indexed& x, std::size_t min_voxels,
                                                            std::vector<KeptLabel>& kept) {
  const Dims d = x.dims;
  const std::size_t n = d.count(), sy = d.nx, sz = d.nx * d.ny;
  std::vector<std::uint32_t> comp(n, 0);  // 0 = not visited, else component id
  std::vector<std::uint32_t> stack, members;
  std::vector<std::size_t> sizes(1, 0);        // per component id (0 unused)
  std::vector<std::uint16_t> label_of(1, 0);  // per component id
  std::size_t ncomp = 0, nvox = 0;
  std::uint32_t id = 0;
  for (std::size_t s = 0; s < n; ++s) {
    if (comp[s] || x.idx[s] == kEmpty) continue;
    const std::uint16_t l = x.idx[s];
    ++id;
    members.clear();
    stack.assign(1, std::uint32_t(s));
    comp[s] = id;
    while (!stack.empty()) {
      const std::size_t c = stack.back();
      stack.pop_back();
      members.push_back(std::uint32_t(c));
      const std::size_t i = c % d.nx, j = (c / d.nx) % d.ny, k = c / sz;
      auto visit = [&](std::size_t q) {
        if (!comp[q] && x.idx[q] == l) {
          comp[q] = id;
          stack.push_back(std::uint32_t(q));
        }
      };
      if (i > 0) visit(c - 1);
      if (i + 1 < d.nx) visit(c + 1);
      if (j > 0) visit(c - sy);
      if (j + 1 < d.ny) visit(c + sy);
      if (k > 0) visit(c - sz);
      if (k + 1 < d.nz) visit(c + sz);
    }
    sizes.push_back(members.size());
    label_of.push_back(l);
  }
  // Per label: its largest component, and whether any is big enough to stay.
  const std::size_t nl = x.values.size();
  std::vector<std::uint32_t> largest(nl, 0);
  std::vector<char> has_big(nl, 0);
  for (std::uint32_t c = 1; c <= id; ++c) {
    const std::uint16_t l = label_of[c];
    if (sizes[c] >= min_voxels) has_big[l] = 1;
    if (!largest[l] || sizes[c] > sizes[largest[l]]) largest[l] = c;
  }
  for (std::size_t l = 0; l < nl; ++l)
    if (largest[l] && !has_big[l]) kept.push_back({x.values[l], "min_component", sizes[largest[l]]});
  for (std::uint32_t c = 1; c <= id; ++c)
    if (sizes[c] < min_voxels && !(largest[label_of[c]] == c && !has_big[label_of[c]])) {
      ++ncomp;
      nvox += sizes[c];
    }
  for (std::size_t v = 0; v < n; ++v) {
    const std::uint32_t c = comp[v];
    if (c && sizes[c] < min_voxels && !(largest[label_of[c]] == c && !has_big[label_of[c]])) x.idx[v] = kEmpty;
  }
  return {ncomp, nvox};
}

// Labels that downsampling left without a voxel: each takes the output voxel
// whose block holds most of its input voxels, among those whose current label
// keeps other voxels (ties: the first such voxel); appended to `kept`, or to
// `lost` when no such voxel exists.
void keep_downsampled_labels(const Indexed& in, Indexed& out, int k, const std::vector<std::size_t>& before,
                             std::vector<KeptLabel>& kept, std::vector<std::int64_t>& lost) {
  std::vector<std::size_t> after = index_counts(out);
  const Dims d = in.dims, od = out.dims;
  const auto kk = std::size_t(k);
  for (std::size_t l = 0; l < in.values.size(); ++l) {
    if (before[l] == 0 || after[l] > 0) continue;
    std::unordered_map<std::size_t, std::size_t> in_block;  // output voxel -> voxels of l in its block
    for (std::size_t z = 0, v = 0; z < d.nz; ++z)
      for (std::size_t y = 0; y < d.ny; ++y)
        for (std::size_t x = 0; x < d.nx; ++x, ++v)
          if (in.idx[v] == l) ++in_block[x / kk + od.nx * (y / kk + od.ny * (z / kk))];
    std::size_t best = std::size_t(-1), best_count = 0;
    for (const auto& [o, c] : in_block) {
      const std::uint16_t cur = out.idx[o];
      if (cur != kEmpty && after[cur] < 2) continue;
      if (c > best_count || (c == best_count && o < best)) {
        best = o;
        best_count = c;
      }
    }
    if (best == std::size_t(-1)) {
      lost.push_back(in.values[l]);
      continue;
    }
    if (out.idx[best] != kEmpty) --after[out.idx[best]];
    out.idx[best] = std::uint16_t(l);
    after[l] = 1;
    kept.push_back({in.values[l], "downsample", 1});
  }
}

void check_factor(int k) {
  if (k < 1) throw UsageError("downsample factor " + std::to_string(k) + "; expected an integer >= 1");
}

}  // namespace

// ---------------------------------------------------------------------------
// Masks
// ---------------------------------------------------------------------------

Volume morph_mask(const Volume& mask, const std::vector<MorphStep>& steps) {
  check_steps(steps);
  const Dims d = mask.dims();
  BBox b;
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      for (std::size_t i = 0; i < d.nx; ++i)
        if (mask.get(i, j, k) != 0) b.add(long(i), long(j), long(k));
  Volume out(VoxelType::u8, d, mask.geometry());
  if (b.empty()) return out;  // nothing in, nothing out (dilation of the empty set is empty)
  Region r = make_region(b, growth(steps) + 1);
  for_region_in_volume(r, d, [&](std::size_t ri, std::size_t vi) { r.a[ri] = mask.get(vi) != 0; });
  run_steps(r, steps);
  std::uint8_t* o = out.data<std::uint8_t>();
  for_region_in_volume(r, d, [&](std::size_t ri, std::size_t vi) { o[vi] = r.a[ri]; });
  return out;
}

Volume erode(const Volume& mask, const MorphParams& p) {
  return morph_mask(mask, {MorphStep{MorphOp::erode, p.stencil, p.iterations}});
}
Volume dilate(const Volume& mask, const MorphParams& p) {
  return morph_mask(mask, {MorphStep{MorphOp::dilate, p.stencil, p.iterations}});
}
Volume opening(const Volume& mask, const MorphParams& p) {
  return morph_mask(mask, {MorphStep{MorphOp::open, p.stencil, p.iterations}});
}
Volume closing(const Volume& mask, const MorphParams& p) {
  return morph_mask(mask, {MorphStep{MorphOp::close, p.stencil, p.iterations}});
}

// ---------------------------------------------------------------------------
// Label maps
// ---------------------------------------------------------------------------

LabelMorphResult morph_labels(const Volume& labels, const LabelMorphParams& p) {
  check_factor(p.downsample);
  check_steps(p.steps);
  for (const auto& [l, s] : p.per_label) check_steps(s);
  Indexed x = index_labels(labels, "morph_labels");
  LabelMorphResult res;
  res.counts_before = counts_of(x);
  const std::size_t nl = x.values.size();

  // Processed labels and their sequences.
  std::vector<char> processed(nl, 0);
  auto index_of = [&](std::int64_t l) -> long {
    const auto it = std::lower_bound(x.values.begin(), x.values.end(), l);
    return it != x.values.end() && *it == l ? long(it - x.values.begin()) : -1;
  };
  auto absent = [&](std::int64_t l, const char* where) {
    std::ostringstream m;
    m << "morph_labels: label " << l << " (" << where << ") does not occur; labels present:";
    std::size_t shown = 0;
    for (auto v : x.values) {
      if (shown++ == 32) { m << " ..."; break; }
      m << " " << v;
    }
    return InputError(m.str());
  };
  if (p.all_labels) {
    for (std::size_t a = 0; a < nl; ++a) processed[a] = 1;
  } else if (p.labels.empty()) {
    for (std::size_t a = 0; a < nl; ++a) processed[a] = x.values[a] != 0;
  } else {
    for (std::int64_t l : p.labels) {
      const long a = index_of(l);
      if (a < 0) throw absent(l, "in the processed labels");
      processed[std::size_t(a)] = 1;
    }
  }
  std::vector<const std::vector<MorphStep>*> seq(nl, &p.steps);
  for (const auto& [l, s] : p.per_label) {
    const long a = index_of(l);
    if (a < 0) throw absent(l, "given its own sequence");
    seq[std::size_t(a)] = &s;
    processed[std::size_t(a)] = 1;
  }
  bool any_steps = false;
  for (std::size_t a = 0; a < nl; ++a) any_steps |= processed[a] && !seq[a]->empty();

  if (any_steps) {
    const Dims d = x.dims;
    // Each label's bounding box: per slice in parallel, then merged (a union
    // of boxes does not depend on the order).
    std::vector<BBox> slice_boxes(d.nz * nl);
    pm::parallel_for(std::size_t(0), d.nz, [&](std::size_t k) {
      BBox* b = slice_boxes.data() + k * nl;
      for (std::size_t j = 0, v = d.nx * d.ny * k; j < d.ny; ++j)
        for (std::size_t i = 0; i < d.nx; ++i, ++v) b[x.idx[v]].add(long(i), long(j), long(k));
    });
    std::vector<BBox> boxes(nl);
    for (std::size_t k = 0; k < d.nz; ++k)
      for (std::size_t a = 0; a < nl; ++a) {
        const BBox& b = slice_boxes[k * nl + a];
        if (b.empty()) continue;
        boxes[a].add(b.lo[0], b.lo[1], b.lo[2]);
        boxes[a].add(b.hi[0], b.hi[1], b.hi[2]);
      }
    std::vector<std::uint16_t> state(x.idx.size(), kEmpty);
    // Ascending label order: the first claimer of a voxel is the smallest; the
    // original label overrides when it claims the voxel too.
    for (std::size_t a = 0; a < nl; ++a) {
      if (!processed[a] || boxes[a].empty()) continue;
      Region r = make_region(boxes[a], growth(*seq[a]) + 1);
      const auto li = std::uint16_t(a);
      // Row by row with plain pointers (loops the compiler vectorises).
      for_region_rows_in_volume(r, d, [&](std::size_t ri, std::size_t vi, std::size_t n) {
        std::uint8_t* __restrict ra = r.a.data() + ri;
        const std::uint16_t* __restrict xi = x.idx.data() + vi;
        for (std::size_t t = 0; t < n; ++t) ra[t] = xi[t] == li;
      });
      run_steps(r, *seq[a]);
      for_region_rows_in_volume(r, d, [&](std::size_t ri, std::size_t vi, std::size_t n) {
        const std::uint8_t* __restrict ra = r.a.data() + ri;
        const std::uint16_t* __restrict xi = x.idx.data() + vi;
        std::uint16_t* __restrict st = state.data() + vi;
        for (std::size_t t = 0; t < n; ++t)
          st[t] = ra[t] && (xi[t] == li || st[t] == kEmpty) ? li : st[t];
      });
    }
    pm::parallel_for(tbb::blocked_range<std::size_t>(0, state.size()), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t v = r.begin(); v != r.end(); ++v)
        if (state[v] == kEmpty && !processed[x.idx[v]]) state[v] = x.idx[v];
    });
    // Never erase a material: a processed label its own steps left without a
    // voxel gets its input voxels back. A passive label (typically the
    // background) that other labels' dilations cover was asked for.
    std::vector<char> present(nl, 0);
    {
      const std::vector<std::size_t> c = index_counts(state, nl);
      for (std::size_t a = 0; a < nl; ++a) present[a] = c[a] > 0;
    }
    for (std::size_t a = 0; a < nl; ++a) {
      if (present[a] || !processed[a]) continue;
      std::size_t n = 0;
      for (std::size_t v = 0; v < state.size(); ++v)
        if (x.idx[v] == a) {
          state[v] = std::uint16_t(a);
          ++n;
        }
      if (n) res.kept.push_back({x.values[a], "morphology", n});
    }
    x.idx.swap(state);
  }

  if (p.downsample > 1) {
    const std::vector<std::size_t> before = index_counts(x);
    Indexed o = downsample_indices(x, p.downsample);
    keep_downsampled_labels(x, o, p.downsample, before, res.kept, res.lost);
    x = std::move(o);
  }
  if (p.min_component > 1) {
    if (x.idx.size() >= std::size_t(std::numeric_limits<std::uint32_t>::max()))
      throw InputError("morph_labels: --min-component needs fewer than 2^32 voxels");
    const auto [nc, nv] = remove_small_components(x, p.min_component, res.kept);
    res.components_removed = nc;
    res.component_voxels_removed = nv;
  }
  for (std::uint16_t v : x.idx) res.empty += v == kEmpty;
  if (p.vote || res.component_voxels_removed) res.vote_rounds = vote_indices(x, "morph_labels");
  const Geometry g = p.downsample > 1 ? downsampled_geometry(labels.geometry(), p.downsample) : labels.geometry();
  res.labels = write_labels(x, labels.type(), g, p.fill);
  res.counts_after = counts_of(x);
  if (!p.vote && !res.component_voxels_removed && res.empty) res.counts_after[p.fill] += res.empty;
  return res;
}

VoteResult vote_fill(const Volume& labels, std::int64_t empty) {
  Indexed x = index_labels(labels, "vote_fill");
  VoteResult res;
  const auto it = std::lower_bound(x.values.begin(), x.values.end(), empty);
  if (it == x.values.end() || *it != empty) {
    res.labels = labels;
    return res;
  }
  const auto e = std::uint16_t(it - x.values.begin());
  for (auto& v : x.idx)
    if (v == e) {
      v = kEmpty;
      ++res.filled;
    }
  res.rounds = vote_indices(x, "vote_fill");
  res.labels = write_labels(x, labels.type(), labels.geometry(), empty);
  return res;
}

Volume downsample(const Volume& v, int k, DownsampleMode mode) {
  check_factor(k);
  if (mode == DownsampleMode::majority) {
    const Indexed x = index_labels(v, "downsample");
    return write_labels(downsample_indices(x, k), v.type(), downsampled_geometry(v.geometry(), k), 0);
  }
  const Dims od = downsampled_dims(v.dims(), k);
  Volume out(v.type(), od, downsampled_geometry(v.geometry(), k));
  for_blocks(v.dims(), od, k, [&](std::size_t oi, const std::vector<std::size_t>& block) {
    double s = 0;
    for (std::size_t b : block) s += v.get(b);
    out.set(oi, s / double(block.size()));
  });
  return out;
}

}  // namespace pm
