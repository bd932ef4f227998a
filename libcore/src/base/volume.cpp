#include "pm/base/volume.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>

#include "pm/base/error.h"

namespace pm {

const char* voxel_type_name(VoxelType t) {
  switch (t) {
    case VoxelType::u8: return "uint8";
    case VoxelType::i8: return "int8";
    case VoxelType::u16: return "uint16";
    case VoxelType::i16: return "int16";
    case VoxelType::u32: return "uint32";
    case VoxelType::i32: return "int32";
    case VoxelType::u64: return "uint64";
    case VoxelType::i64: return "int64";
    case VoxelType::f32: return "float";
    case VoxelType::f64: return "double";
  }
  return "?";
}

std::size_t voxel_size(VoxelType t) {
  switch (t) {
    case VoxelType::u8: case VoxelType::i8: return 1;
    case VoxelType::u16: case VoxelType::i16: return 2;
    case VoxelType::u32: case VoxelType::i32: case VoxelType::f32: return 4;
    case VoxelType::u64: case VoxelType::i64: case VoxelType::f64: return 8;
  }
  return 0;
}

bool is_integer(VoxelType t) { return t != VoxelType::f32 && t != VoxelType::f64; }

VoxelType parse_voxel_type(const std::string& n) {
  static const std::pair<const char*, VoxelType> names[] = {
      {"uint8", VoxelType::u8},   {"u8", VoxelType::u8},     {"uchar", VoxelType::u8},
      {"int8", VoxelType::i8},    {"i8", VoxelType::i8},     {"uint16", VoxelType::u16},
      {"u16", VoxelType::u16},    {"ushort", VoxelType::u16}, {"int16", VoxelType::i16},
      {"i16", VoxelType::i16},    {"short", VoxelType::i16}, {"uint32", VoxelType::u32},
      {"u32", VoxelType::u32},    {"int32", VoxelType::i32}, {"i32", VoxelType::i32},
      {"int", VoxelType::i32},    {"uint64", VoxelType::u64}, {"u64", VoxelType::u64},
      {"int64", VoxelType::i64},  {"i64", VoxelType::i64},   {"float", VoxelType::f32},
      {"f32", VoxelType::f32},    {"double", VoxelType::f64}, {"f64", VoxelType::f64}};
  for (const auto& [s, t] : names)
    if (n == s) return t;
  throw UsageError("unknown voxel type \"" + n +
                   "\"; expected one of uint8 int8 uint16 int16 uint32 int32 uint64 int64 float double");
}

Vec3 Geometry::world_to_index(const Vec3& x) const { return inverse(directions) * (x - origin); }

bool Geometry::axis_aligned() const {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (i != j && directions.m[i][j] != 0.0) return false;
  return true;
}

Geometry with_world_signs(const Geometry& g, const Vec3& s) {
  // + 0.0 turns the -0 of a negated 0 into 0 (headers then read "0", not "-0").
  Geometry r = g;
  for (int row = 0; row < 3; ++row) {
    r.origin[row] = s[row] * g.origin[row] + 0.0;
    for (int c = 0; c < 3; ++c) r.directions[row][c] = s[row] * g.directions[row][c] + 0.0;
  }
  return r;
}

Geometry Geometry::with_spacing(double sx, double sy, double sz, Vec3 origin) {
  Geometry g;
  g.origin = origin;
  g.directions = Mat3::diag(sx, sy, sz);
  return g;
}

Volume::Volume(VoxelType type, Dims dims, Geometry geometry)
    : type_(type), dims_(dims), geometry_(geometry) {
  if (dims.nx == 0 || dims.ny == 0 || dims.nz == 0) {
    std::ostringstream m;
    m << "volume size " << dims.nx << "x" << dims.ny << "x" << dims.nz
      << " has a zero-size axis; expected every axis >= 1";
    throw InputError(m.str());
  }
  const std::size_t limit = std::numeric_limits<std::size_t>::max() / 8;
  if (dims.nx > limit / dims.ny || dims.nx * dims.ny > limit / dims.nz) {
    std::ostringstream m;
    m << "volume size " << dims.nx << "x" << dims.ny << "x" << dims.nz << " overflows";
    throw InputError(m.str());
  }
  if (std::fabs(determinant(geometry.directions)) <= 0 ||
      !std::isfinite(determinant(geometry.directions)))
    throw InputError("volume geometry: space directions are singular or non-finite; expected three independent axes with spacing > 0");
  bytes_.assign(dims.count() * voxel_size(type), 0);
}

namespace {
template <class T>
T convert_to(double v) {
  if constexpr (std::is_floating_point_v<T>) {
    return static_cast<T>(v);
  } else {
    if (std::isnan(v)) return T(0);
    const double r = std::nearbyint(v);
    if (r <= static_cast<double>(std::numeric_limits<T>::lowest())) return std::numeric_limits<T>::lowest();
    if (r >= static_cast<double>(std::numeric_limits<T>::max())) return std::numeric_limits<T>::max();
    return static_cast<T>(r);
  }
}
template <class T> constexpr VoxelType type_of();
template <> constexpr VoxelType type_of<std::uint8_t>() { return VoxelType::u8; }
template <> constexpr VoxelType type_of<std::int8_t>() { return VoxelType::i8; }
template <> constexpr VoxelType type_of<std::uint16_t>() { return VoxelType::u16; }
template <> constexpr VoxelType type_of<std::int16_t>() { return VoxelType::i16; }
template <> constexpr VoxelType type_of<std::uint32_t>() { return VoxelType::u32; }
template <> constexpr VoxelType type_of<std::int32_t>() { return VoxelType::i32; }
template <> constexpr VoxelType type_of<std::uint64_t>() { return VoxelType::u64; }
template <> constexpr VoxelType type_of<std::int64_t>() { return VoxelType::i64; }
template <> constexpr VoxelType type_of<float>() { return VoxelType::f32; }
template <> constexpr VoxelType type_of<double>() { return VoxelType::f64; }
}  // namespace

double Volume::get(std::size_t idx) const {
  return visit_voxel_type(type_, [&](auto tag) -> double {
    using T = decltype(tag);
    T v;
    std::memcpy(&v, bytes_.data() + idx * sizeof(T), sizeof(T));
    return static_cast<double>(v);
  });
}

void Volume::set(std::size_t idx, double value) {
  visit_voxel_type(type_, [&](auto tag) {
    using T = decltype(tag);
    const T v = convert_to<T>(value);
    std::memcpy(bytes_.data() + idx * sizeof(T), &v, sizeof(T));
    return 0;
  });
}

template <class T>
T* Volume::data() {
  if (type_of<T>() != type_)
    throw Error(std::string("Volume::data: voxel type is ") + voxel_type_name(type_) + ", requested " +
                voxel_type_name(type_of<T>()));
  return reinterpret_cast<T*>(bytes_.data());
}
template <class T>
const T* Volume::data() const {
  return const_cast<Volume*>(this)->data<T>();
}
#define PM_INST(T) template T* Volume::data<T>(); template const T* Volume::data<T>() const;
PM_INST(std::uint8_t) PM_INST(std::int8_t) PM_INST(std::uint16_t) PM_INST(std::int16_t)
PM_INST(std::uint32_t) PM_INST(std::int32_t) PM_INST(std::uint64_t) PM_INST(std::int64_t)
PM_INST(float) PM_INST(double)
#undef PM_INST

std::vector<float> Volume::to_float() const {
  std::vector<float> out(count());
  visit_voxel_type(type_, [&](auto tag) {
    using T = decltype(tag);
    const T* p = reinterpret_cast<const T*>(bytes_.data());
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = static_cast<float>(p[i]);
    return 0;
  });
  return out;
}

std::vector<double> Volume::to_double() const {
  std::vector<double> out(count());
  visit_voxel_type(type_, [&](auto tag) {
    using T = decltype(tag);
    const T* p = reinterpret_cast<const T*>(bytes_.data());
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = static_cast<double>(p[i]);
    return 0;
  });
  return out;
}

Volume Volume::converted(VoxelType t) const {
  Volume out(t, dims_, geometry_);
  const std::size_t n = count();
  // Typed loops: each voxel as get() reads it (a double), stored as set()
  // stores it (convert_to), without two calls per voxel.
  visit_voxel_type(type_, [&](auto from) {
    using S = decltype(from);
    const S* src = reinterpret_cast<const S*>(bytes_.data());
    return visit_voxel_type(t, [&](auto to) {
      using T = decltype(to);
      T* dst = reinterpret_cast<T*>(out.bytes_.data());
      for (std::size_t i = 0; i < n; ++i) dst[i] = convert_to<T>(static_cast<double>(src[i]));
      return 0;
    });
  });
  return out;
}

double exact_within(const Volume& sdf, bool positive_side, const std::string& what) {
  const char* key = positive_side ? kExactPositiveKey : kExactNegativeKey;
  const std::string v = sdf.key(key);
  if (v.empty()) return HUGE_VAL;
  char* end = nullptr;
  const double w = std::strtod(v.c_str(), &end);
  if (end == v.c_str() || *end != '\0' || !(w > 0) || !std::isfinite(w))
    throw InputError(what + ": key " + key + " is \"" + v + "\"; expected a distance > 0 (world units)");
  return w;
}

Box Volume::world_bounds() const {
  Box b;
  for (int c = 0; c < 8; ++c) {
    Vec3 ijk((c & 1) ? dims_.nx - 1.0 : 0.0, (c & 2) ? dims_.ny - 1.0 : 0.0, (c & 4) ? dims_.nz - 1.0 : 0.0);
    b.extend(geometry_.index_to_world(ijk));
  }
  return b;
}

namespace {
constexpr std::size_t kScanGrain = std::size_t(1) << 18;  // voxels per chunk of the parallel scans
}  // namespace

void require_finite(const Volume& v, const std::string& what) {
  if (is_integer(v.type())) return;
  const std::size_t n = v.count();
  // The first non-finite voxel by typed loops over chunks in parallel: the
  // smallest index found, the same voxel whatever the schedule.
  const std::size_t bad = visit_voxel_type(v.type(), [&](auto tag) -> std::size_t {
    using T = decltype(tag);
    const T* p = static_cast<const T*>(v.raw());
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, kScanGrain), n,
        [&](const tbb::blocked_range<std::size_t>& r, std::size_t first) {
          if (first < r.begin()) return first;
          for (std::size_t i = r.begin(); i != r.end(); ++i)
            if (!std::isfinite(static_cast<double>(p[i]))) return i;
          return first;
        },
        [](std::size_t a, std::size_t b) { return std::min(a, b); });
  });
  for (std::size_t i = bad; i < n; ++i) {
    const double x = v.get(i);
    if (!std::isfinite(x)) {
      const std::size_t ii = i % v.dims().nx, jj = (i / v.dims().nx) % v.dims().ny,
                        kk = i / (v.dims().nx * v.dims().ny);
      std::ostringstream m;
      m << what << ": voxel (" << ii << "," << jj << "," << kk << ") is " << x
        << "; expected finite values";
      throw InputError(m.str());
    }
  }
}

ValueRange value_range(const Volume& v) {
  ValueRange r{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  const std::size_t n = v.count();
  // Typed loops over chunks in parallel, joined left to right. NaN voxels
  // are skipped (std::min and std::max keep the first argument on NaN), and
  // of equal values (0 and -0) the first is kept, as in one serial loop.
  return visit_voxel_type(v.type(), [&](auto tag) {
    using T = decltype(tag);
    const T* p = static_cast<const T*>(v.raw());
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, kScanGrain), r,
        [&](const tbb::blocked_range<std::size_t>& b, ValueRange acc) {
          for (std::size_t i = b.begin(); i != b.end(); ++i) {
            const double x = static_cast<double>(p[i]);
            acc.lo = std::min(acc.lo, x);
            acc.hi = std::max(acc.hi, x);
          }
          return acc;
        },
        [](ValueRange a, const ValueRange& b) {
          a.lo = std::min(a.lo, b.lo);
          a.hi = std::max(a.hi, b.hi);
          return a;
        });
  });
}

VoxelType smallest_integer_type(const Volume& v) {
  if (!is_integer(v.type()))
    throw InputError(std::string("smallest integer type: the volume holds ") + voxel_type_name(v.type()) +
                     " voxels; expected an integer volume (a label map)");
  if (v.count() == 0) return VoxelType::u8;
  const ValueRange r = value_range(v);
  const VoxelType unsigned_types[] = {VoxelType::u8, VoxelType::u16, VoxelType::u32};
  const VoxelType signed_types[] = {VoxelType::i8, VoxelType::i16, VoxelType::i32};
  const double lo_s[] = {-128.0, -32768.0, -2147483648.0}, hi_s[] = {127.0, 32767.0, 2147483647.0};
  const double hi_u[] = {255.0, 65535.0, 4294967295.0};
  for (int b = 0; b < 3; ++b) {
    if (r.lo >= 0 && r.hi <= hi_u[b]) return unsigned_types[b];
    if (r.lo < 0 && r.lo >= lo_s[b] && r.hi <= hi_s[b]) return signed_types[b];
  }
  return v.type();
}

Volume padded(const Volume& v, std::size_t n, double value) {
  const Dims& d = v.dims();
  const Dims e{d.nx + 2 * n, d.ny + 2 * n, d.nz + 2 * n};
  Geometry g = v.geometry();
  g.origin = g.index_to_world(Vec3(-double(n), -double(n), -double(n)));
  Volume out(v.type(), e, g);
  const std::size_t bytes = v.count() ? v.byte_size() / v.count() : 0;
  auto* dst = static_cast<unsigned char*>(out.raw());
  if (value != 0)
    visit_voxel_type(v.type(), [&](auto tag) {
      using T = decltype(tag);
      const T x = convert_to<T>(value);  // as set() stores it
      std::fill_n(reinterpret_cast<T*>(dst), out.count(), x);
      return 0;
    });
  const auto* src = static_cast<const unsigned char*>(v.raw());
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      std::memcpy(dst + out.index(n, j + n, k + n) * bytes, src + v.index(0, j, k) * bytes, d.nx * bytes);
  return out;
}

}  // namespace pm

namespace pm {

Volume with_positive_steps(const Volume& v, const std::string& what) {
  const Mat3& d = v.geometry().directions;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      if ((r != c && d[r][c] != 0.0) || (r == c && d[r][c] == 0.0))
        throw InputError(what + ": the volume has oblique axes; expected axis-aligned directions (a diagonal matrix)");
  const bool flip[3] = {d[0][0] < 0, d[1][1] < 0, d[2][2] < 0};
  if (!flip[0] && !flip[1] && !flip[2]) return v;
  const Dims& n = v.dims();
  Geometry g = v.geometry();
  for (int a = 0; a < 3; ++a) {
    if (!flip[a]) continue;
    g.origin[a] += d[a][a] * double(n[a] - 1);
    g.directions[a][a] = -d[a][a];
  }
  Volume out(v.type(), n, g);
  out.set_frame_source(v.frame_source());
  const std::size_t vs = voxel_size(v.type());
  const auto* in = static_cast<const unsigned char*>(v.raw());
  auto* o = static_cast<unsigned char*>(out.raw());
  for (std::size_t k = 0; k < n.nz; ++k)
    for (std::size_t j = 0; j < n.ny; ++j)
      for (std::size_t i = 0; i < n.nx; ++i) {
        const std::size_t si = flip[0] ? n.nx - 1 - i : i, sj = flip[1] ? n.ny - 1 - j : j,
                          sk = flip[2] ? n.nz - 1 - k : k;
        std::memcpy(o + out.index(i, j, k) * vs, in + v.index(si, sj, sk) * vs, vs);
      }
  return out;
}

}  // namespace pm
