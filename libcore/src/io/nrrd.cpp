#include "pm/io/nrrd.h"

#include <teem/nrrd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <sstream>
#include <utility>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/gzip.h"
#include "pm/io/volume_header.h"

namespace fs = std::filesystem;

namespace pm {
namespace {

// Teem keeps its error messages in one global table (biff) that is not
// thread-safe: calls into Teem take turns, so volumes can be read side by
// side (pm::parallel_tasks) and each error still names its own file.
std::recursive_mutex& teem_mutex() {
  static std::recursive_mutex m;
  return m;
}

// Teem's accumulated error text for NRRD, reduced to its innermost reason
// (Teem lists the outermost call first), plus the header field being parsed
// when there was one: `axis 1 size is zero! (in "sizes: 2 0 2")`.
std::string teem_error() {
  char* err = biffGetDone(NRRD);
  if (!err) return "unknown Teem error";
  std::string text(err);
  std::free(err);
  std::istringstream in(text);
  std::string line, last, field;
  while (std::getline(in, line)) {
    if (line.rfind("[nrrd] ", 0) == 0) line = line.substr(7);
    while (!line.empty() && (line.back() == ' ' || line.back() == '\r' || line.back() == ':')) line.pop_back();
    const auto colon = line.find(": ");
    if (colon != std::string::npos && line.find(' ') > colon) line = line.substr(colon + 2);  // "fn: msg"
    if (line.empty()) continue;
    const std::string parsing = "trouble parsing ";
    if (line.rfind(parsing, 0) == 0) {
      const auto info = line.find(" info |");
      if (info != std::string::npos && line.back() == '|')
        field = line.substr(parsing.size(), info - parsing.size()) + ": " +
                line.substr(info + 7, line.size() - info - 8);
    }
    last = line;
  }
  if (last.empty()) last = text;
  return field.empty() ? last : last + " (in \"" + field + "\")";
}

// RAII owners for Teem structures.
struct NrrdHolder {
  Nrrd* n = nrrdNew();
  bool owns_data = true;
  ~NrrdHolder() {
    if (owns_data) nrrdNuke(n);
    else nrrdNix(n);
  }
};
struct NioHolder {
  NrrdIoState* nio = nrrdIoStateNew();
  FILE* header = nullptr;  // the file load() opened
  // nrrdLoad() as Teem 1.12 does it, except that the header file stays ours.
  // nrrdLoad closes the file it opened when the read fails, while
  // nio->dataFile may still name that very file (attached data), and the
  // destructor, which must close a data file Teem left open, closed it a
  // second time (fuzz_sizing, tests/data/regress/sizing-gzip-double-fclose).
  int load(Nrrd* n, const std::string& path) {
    // The header's folder, as Teem's _nrrdSplitName finds it: detached data
    // files are named relative to it.
    const std::size_t slash = path.rfind('/');
    nio->path = static_cast<char*>(airFree(nio->path));
    nio->path = airStrdup(slash != std::string::npos && slash + 1 < path.size() ? path.substr(0, slash).c_str() : ".");
    header = std::fopen(path.c_str(), "rb");
    if (!header) {
      biffAddf(NRRD, "%s: fopen(\"%s\",\"rb\") failed: %s", "nrrdLoad", path.c_str(), std::strerror(errno));
      return 2;
    }
    return nrrdRead(n, header, nio);
  }
  ~NioHolder() {
    if (nio->dataFile && nio->dataFile != stdin && nio->dataFile != header) std::fclose(nio->dataFile);
    if (header) std::fclose(header);
    nio->dataFile = nullptr;
    nrrdIoStateNix(nio);
  }
};

bool from_teem_type(int t, VoxelType& out) {
  switch (t) {
    case nrrdTypeChar: out = VoxelType::i8; return true;
    case nrrdTypeUChar: out = VoxelType::u8; return true;
    case nrrdTypeShort: out = VoxelType::i16; return true;
    case nrrdTypeUShort: out = VoxelType::u16; return true;
    case nrrdTypeInt: out = VoxelType::i32; return true;
    case nrrdTypeUInt: out = VoxelType::u32; return true;
    case nrrdTypeLLong: out = VoxelType::i64; return true;
    case nrrdTypeULLong: out = VoxelType::u64; return true;
    case nrrdTypeFloat: out = VoxelType::f32; return true;
    case nrrdTypeDouble: out = VoxelType::f64; return true;
    default: return false;
  }
}

int to_teem_type(VoxelType t) {
  switch (t) {
    case VoxelType::i8: return nrrdTypeChar;
    case VoxelType::u8: return nrrdTypeUChar;
    case VoxelType::i16: return nrrdTypeShort;
    case VoxelType::u16: return nrrdTypeUShort;
    case VoxelType::i32: return nrrdTypeInt;
    case VoxelType::u32: return nrrdTypeUInt;
    case VoxelType::i64: return nrrdTypeLLong;
    case VoxelType::u64: return nrrdTypeULLong;
    case VoxelType::f32: return nrrdTypeFloat;
    case VoxelType::f64: return nrrdTypeDouble;
  }
  return nrrdTypeUnknown;
}

// The world frame a NRRD "space" names, as signs that take its coordinates
// to LPS (x' = s.x * x, ...), and how many of its components are space (the
// "-time" spaces have a fourth, time). Returns false for a space we cannot
// take to 3-D LPS (the 2-D ones).
struct SpaceMap {
  Vec3 signs{1, 1, 1};
  unsigned dims = 3;  // components of the space ("space dimension")
  bool anatomical = true;
};
bool space_to_lps(int space, SpaceMap& m) {
  switch (space) {
    case nrrdSpaceRightAnteriorSuperior: m = {{-1, -1, 1}, 3, true}; return true;
    case nrrdSpaceLeftAnteriorSuperior: m = {{1, -1, 1}, 3, true}; return true;
    case nrrdSpaceLeftPosteriorSuperior: m = {{1, 1, 1}, 3, true}; return true;
    case nrrdSpaceRightAnteriorSuperiorTime: m = {{-1, -1, 1}, 4, true}; return true;
    case nrrdSpaceLeftAnteriorSuperiorTime: m = {{1, -1, 1}, 4, true}; return true;
    case nrrdSpaceLeftPosteriorSuperiorTime: m = {{1, 1, 1}, 4, true}; return true;
    // DICOM's (and ACR/NEMA's) scanner frame is patient LPS, as ITK reads it.
    case nrrdSpaceScannerXYZ: m = {{1, 1, 1}, 3, true}; return true;
    case nrrdSpaceScannerXYZTime: m = {{1, 1, 1}, 4, true}; return true;
    // No anatomy: the coordinates are kept as they are.
    case nrrdSpace3DRightHanded:
    case nrrdSpace3DLeftHanded: m = {{1, 1, 1}, 3, false}; return true;
    case nrrdSpace3DRightHandedTime:
    case nrrdSpace3DLeftHandedTime: m = {{1, 1, 1}, 4, false}; return true;
    default: return false;
  }
}

// Geometry from the header, in LPS: space origin + space directions when the
// NRRD has a space (converted from the named space), else per-axis spacings
// (and axis mins as the origin), kept as given.
Geometry nrrd_geometry(const Nrrd* n, const std::string& path, FrameSource& frame) {
  const std::string who = "read_nrrd";
  const std::string where = who + ": " + quote(path);
  Geometry g;
  frame.format = "NRRD";
  if (n->space != nrrdSpaceUnknown || n->spaceDim > 0) {
    SpaceMap map;
    if (n->space != nrrdSpaceUnknown) {
      const std::string name = airEnumStr(nrrdSpace, n->space);
      if (!space_to_lps(n->space, map))
        throw InputError(where + ": space \"" + name + "\" is " + std::to_string(n->spaceDim) +
                         "-D; expected a 3-D space (right-anterior-superior, left-posterior-superior, "
                         "left-anterior-superior, scanner-xyz, 3D-right-handed, 3D-left-handed or their -time "
                         "forms)");
      if (n->spaceDim != map.dims) {
        std::ostringstream m;
        m << where << ": space \"" << name << "\" has " << map.dims << " dimensions but the header gives "
          << n->spaceDim << "; expected space directions of " << map.dims << " components";
        throw InputError(m.str());
      }
      frame.space = name;
      frame.anatomical = map.anatomical;
      if (!map.anatomical) frame.note = "space \"" + name + "\" has no anatomy: coordinates kept as given (as LPS)";
    } else {
      if (n->spaceDim != 3) {
        std::ostringstream m;
        m << where << ": space dimension is " << n->spaceDim << "; expected 3";
        throw InputError(m.str());
      }
      frame.space = "none (space dimension 3)";
      frame.anatomical = false;
      frame.note = "no named space: coordinates kept as given (as LPS)";
    }
    Vec3 cols[3];
    for (int a = 0; a < 3; ++a) {
      for (unsigned c = 0; c < map.dims; ++c) {
        const double d = n->axis[a].spaceDirection[c];
        if (std::isnan(d)) {
          std::ostringstream m;
          m << where << ": axis " << a << " has no space direction; expected a direction for each of the 3 axes";
          throw InputError(m.str());
        }
        if (c < 3) cols[a][int(c)] = d;
        else if (d != 0) {
          std::ostringstream m;
          m << where << ": the space direction of axis " << a << " has time component " << d
            << "; expected 0 (3 spatial axes)";
          throw InputError(m.str());
        }
      }
    }
    g.directions = Mat3::from_columns(cols[0], cols[1], cols[2]);
    for (int c = 0; c < 3; ++c) g.origin[c] = std::isnan(n->spaceOrigin[c]) ? 0.0 : n->spaceOrigin[c];
    return with_world_signs(g, map.signs);
  }
  frame.space = "none";
  frame.anatomical = false;
  frame.note = "no space field: spacings and axis mins kept as given (as LPS)";
  double s[3];
  for (int a = 0; a < 3; ++a) {
    const NrrdAxisInfo& ax = n->axis[a];
    const bool cell = ax.center == nrrdCenterCell;
    s[a] = ax.spacing;
    if (std::isnan(s[a])) {
      if (!std::isnan(ax.min) && !std::isnan(ax.max)) {
        const double steps = cell ? double(ax.size) : double(ax.size) - 1.0;
        s[a] = steps > 0 ? (ax.max - ax.min) / steps : 1.0;
      } else {
        s[a] = 1.0;
      }
    }
    check_spacing(who, path, a, s[a]);
    // Samples are nodes: for cell-centred axes the first sample sits half a
    // spacing inside "axis min".
    g.origin[a] = std::isnan(ax.min) ? 0.0 : ax.min + (cell ? 0.5 * s[a] : 0.0);
  }
  g.directions = Mat3::diag(s[0], s[1], s[2]);
  return g;
}

std::uintmax_t file_size_or_zero(const std::string& p) {
  std::error_code ec;
  const auto s = fs::file_size(p, ec);
  return ec ? 0 : s;
}

}  // namespace

Volume read_nrrd(const std::string& path) {
  const std::lock_guard<std::recursive_mutex> teem(teem_mutex());
  const std::string who = "read_nrrd";
  const std::string where = who + ": " + quote(path);
  require_readable(path);

  // Pass 1: header only (no allocation); keep the data file open at the start
  // of its data so the size it holds can be checked against the header.
  Dims dims;
  VoxelType type = VoxelType::f32;
  Geometry geom;
  FrameSource frame;
  {
    NrrdHolder h;
    NioHolder io;
    io.nio->skipData = AIR_TRUE;
    io.nio->keepNrrdDataFileOpen = AIR_TRUE;
    if (io.load(h.n, path)) throw InputError(where + ": " + teem_error());
    if (h.n->dim != 3) {
      std::ostringstream m;
      m << where << ": expected 3 axes, got " << h.n->dim;
      throw InputError(m.str());
    }
    if (!from_teem_type(h.n->type, type)) {
      throw InputError(where + ": voxel type \"" + airEnumStr(nrrdType, h.n->type) +
                       "\" is not supported; expected a scalar integer or floating-point type");
    }
    dims = {h.n->axis[0].size, h.n->axis[1].size, h.n->axis[2].size};
    geom = nrrd_geometry(h.n, path, frame);
    check_volume_header(who, path, dims, geom);

    // Size check against what is left of a single data file.
    const std::uint64_t need = std::uint64_t(dims.count()) * voxel_size(type);
    const NrrdEncoding* enc = io.nio->encoding;
    FILE* df = io.nio->dataFile;
    if (df && enc) {
      const long pos = std::ftell(df);
      std::uint64_t total = 0;
      if (io.nio->dataFNArr && io.nio->dataFNArr->len == 1) {
        std::string name = io.nio->dataFN[0];
        if (!fs::path(name).is_absolute() && io.nio->path) name = (fs::path(io.nio->path) / name).string();
        total = file_size_or_zero(name);
      } else {
        total = file_size_or_zero(path);
      }
      const std::uint64_t avail = (pos >= 0 && std::uint64_t(pos) <= total) ? total - std::uint64_t(pos) : 0;
      const std::string ename = enc->name;
      std::ostringstream m;
      if (ename == "raw" && avail < need) {
        m << where << ": truncated: expected " << need << " bytes of voxel data (" << dims.nx << "x" << dims.ny
          << "x" << dims.nz << " " << voxel_type_name(type) << "), the file holds " << avail;
        throw InputError(m.str());
      }
      if ((ename == "ascii" && dims.count() > avail + 1) || (ename == "hex" && need > avail / 2 + 1)) {
        m << where << ": truncated: " << dims.count() << " " << ename << " values cannot fit in the " << avail
          << " bytes of data";
        throw InputError(m.str());
      }
      if (ename == "gzip" && need > max_inflated_size(avail)) {
        m << where << ": truncated or corrupt: header claims " << need << " bytes of voxel data, " << avail
          << " bytes of gzip data can hold at most " << max_inflated_size(avail);
        throw InputError(m.str());
      }
    }
  }

  // Pass 2: the data.
  NrrdHolder h;
  NioHolder io;
  if (io.load(h.n, path))
    throw InputError(where + ": truncated or corrupt voxel data: " + teem_error());
  const Dims again{h.n->axis[0].size, h.n->axis[1].size, h.n->axis[2].size};
  VoxelType type2;
  if (h.n->dim != 3 || !(again == dims) || !from_teem_type(h.n->type, type2) || type2 != type || !h.n->data)
    throw InputError(where + ": the file changed while it was being read");
  Volume v(type, dims, geom);
  std::memcpy(v.raw(), h.n->data, v.byte_size());
  v.set_frame_source(std::move(frame));
  // The header's key/value pairs (Teem hands out copies).
  for (unsigned i = 0; i < nrrdKeyValueSize(h.n); ++i) {
    char *key = nullptr, *value = nullptr;
    nrrdKeyValueIndex(h.n, &key, &value, i);
    if (key && value) v.set_key(key, value);
    if (!nrrdStateKeyValueReturnInternalPointers) {
      std::free(key);
      std::free(value);
    }
  }
  return v;
}

std::string nhdr_data_path(const std::string& header_path, bool gzip) {
  const fs::path p(header_path);
  const std::string name = p.filename().string();
  const std::string ext = file_extension(header_path);
  const std::string stem = name.substr(0, name.size() - ext.size());
  return (p.parent_path() / (stem + (gzip ? ".raw.gz" : ".raw"))).string();
}

namespace {

// Wrap v's voxels (not copied) in a Nrrd with our geometry.
void wrap_volume(NrrdHolder& h, const Volume& v, const std::string& where) {
  h.owns_data = false;
  const Dims& d = v.dims();
  if (nrrdWrap_va(h.n, const_cast<void*>(v.raw()), to_teem_type(v.type()), 3u, d.nx, d.ny, d.nz))
    throw Error(where + ": " + teem_error());
  // libcore's world frame (see pm/base/volume.h).
  if (nrrdSpaceSet(h.n, nrrdSpaceLeftPosteriorSuperior)) throw Error(where + ": " + teem_error());
  const Geometry& g = v.geometry();
  double origin[NRRD_SPACE_DIM_MAX] = {g.origin.x, g.origin.y, g.origin.z};
  if (nrrdSpaceOriginSet(h.n, origin)) throw Error(where + ": " + teem_error());
  double dir[3][NRRD_SPACE_DIM_MAX];
  for (int a = 0; a < 3; ++a) {
    nrrdSpaceVecSetNaN(dir[a]);
    const Vec3 c = g.directions.column(a);
    for (int k = 0; k < 3; ++k) dir[a][k] = c[k];
  }
  nrrdAxisInfoSet_va(h.n, nrrdAxisInfoSpaceDirection, dir[0], dir[1], dir[2]);
  nrrdAxisInfoSet_va(h.n, nrrdAxisInfoKind, nrrdKindDomain, nrrdKindDomain, nrrdKindDomain);
  for (const auto& [key, value] : v.keys())
    if (nrrdKeyValueAdd(h.n, key.c_str(), value.c_str())) throw Error(where + ": " + teem_error());
}

// zlib's fastest level, as nibabel writes .nii.gz: label maps, masks and
// sizing fields (zero off a band) are long runs and shrink about a
// hundredfold at level 1 too, in half the time of the default level (a 137 MB
// int32 frog label map: 1.1 MB in 0.2 s against 0.38 MB in 0.44 s). Float
// distances barely compress at any level; the tools write those raw.
constexpr int kZlibLevel = 1;

void set_encoding(NrrdIoState* nio, bool gzip, const std::string& where) {
  if (gzip && !nrrdEncodingGzip->available())
    throw IoError(where + ": this Teem build has no gzip encoding; expected one built with zlib");
  nio->encoding = gzip ? nrrdEncodingGzip : nrrdEncodingRaw;
  if (gzip) nio->zlibLevel = kZlibLevel;
}

void set_data_file_name(NrrdIoState* nio, const std::string& name) {
  const unsigned idx = airArrayLenIncr(nio->dataFNArr, 1);
  nio->dataFN[idx] = airStrdup(name.c_str());
}

}  // namespace

void write_nrrd_detached(const Volume& v, const std::string& header_path, const std::string& data_path,
                         const std::string& data_name, bool gzip) {
  const std::lock_guard<std::recursive_mutex> teem(teem_mutex());
  const std::string where = "write_nrrd: " + quote(header_path);
  if (file_extension(header_path) != ".nhdr") throw Error(where + ": a detached header must end in .nhdr");
  if (fs::absolute(fs::path(data_path)).parent_path() != fs::absolute(fs::path(header_path)).parent_path())
    throw Error(where + ": data file " + quote(data_path) + " must be in the header's folder");
  NrrdHolder h;
  wrap_volume(h, v, where);
  {
    // Voxels to data_path (the header written alongside names it; replaced below).
    NioHolder io;
    set_encoding(io.nio, gzip, where);
    io.nio->detachedHeader = AIR_TRUE;
    set_data_file_name(io.nio, fs::path(data_path).filename().string());
    if (nrrdSave(header_path.c_str(), h.n, io.nio)) throw IoError(where + ": " + teem_error());
  }
  if (fs::path(data_path).filename().string() != data_name) {
    // Header only, naming the final data file.
    NioHolder io;
    set_encoding(io.nio, gzip, where);
    io.nio->detachedHeader = AIR_TRUE;
    io.nio->skipData = AIR_TRUE;
    set_data_file_name(io.nio, data_name);
    if (nrrdSave(header_path.c_str(), h.n, io.nio)) throw IoError(where + ": " + teem_error());
  }
}

void write_nrrd(const Volume& v, const std::string& path, bool gzip) {
  const std::lock_guard<std::recursive_mutex> teem(teem_mutex());
  const std::string where = "write_nrrd: " + quote(path);
  if (v.empty()) throw InputError(where + ": the volume is empty");
  if (file_extension(path) == ".nhdr") {
    const std::string data = nhdr_data_path(path, gzip);
    write_nrrd_detached(v, path, data, fs::path(data).filename().string(), gzip);
    return;
  }
  NrrdHolder h;
  wrap_volume(h, v, where);
  NioHolder io;
  set_encoding(io.nio, gzip, where);
  if (nrrdSave(path.c_str(), h.n, io.nio)) throw IoError(where + ": " + teem_error());
}

}  // namespace pm
