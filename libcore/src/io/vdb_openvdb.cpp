// The OpenVDB side of particlemesh, built as the plugin libpmcore_openvdb
// (see openvdb_plugin.h): VDB files, mesh signed distances, marching cubes.
#include "openvdb_plugin.h"

#include <openvdb/io/Compression.h>
#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/math/Transform.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>

#include <dlfcn.h>

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <ios>
#include <limits>
#include <mutex>
#include <new>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/volume_header.h"

// OpenVDB 10.0's io::bloscFromStream (io/Compression.cc) reads an
// uncompressed chunk of the size the file declares into a buffer of the size
// the tree expects, and only then compares the two, so a crafted file writes
// past the buffer (fuzz_vdb, tests/data/regress/vdb-blosc-chunk-overflow;
// later OpenVDB releases compare first). The tree readers that call it are
// templates instantiated in this library, so their calls bind to the
// definitions below: they read the chunk's size, refuse a wrong uncompressed
// size before reading anything, and hand compressed chunks back to OpenVDB's
// own function (found with dlsym(RTLD_NEXT)) with the stream where it was.
// unzipFromStream has the same shape and gets the same guard.
namespace openvdb {
OPENVDB_USE_VERSION_NAMESPACE
namespace OPENVDB_VERSION_NAME {
namespace io {
namespace {
#define PM_VDB_STR2(x) #x
#define PM_VDB_STR(x) PM_VDB_STR2(x)
using ReadChunk = void (*)(std::istream&, char*, size_t);
// OpenVDB's own io::<function>(std::istream&, char*, size_t), by its mangled
// name in this OpenVDB's version namespace; null when it is not there.
ReadChunk openvdb_function(const std::string& function) {
  const std::string ns = PM_VDB_STR(OPENVDB_VERSION_NAME);
  const std::string symbol = "_ZN7openvdb" + std::to_string(ns.size()) + ns + "2io" +
                             std::to_string(function.size()) + function + "ERSiPcm";
  return reinterpret_cast<ReadChunk>(dlsym(RTLD_NEXT, symbol.c_str()));
}
#undef PM_VDB_STR
#undef PM_VDB_STR2
void checked_chunk(std::istream& is, char* data, size_t numBytes, ReadChunk original, const char* what) {
  Int64 n = 0;
  is.read(reinterpret_cast<char*>(&n), 8);
  if (!is.good()) OPENVDB_THROW(RuntimeError, "stream failure reading the size of a " << what << " chunk");
  if (n <= 0) {
    if (n == std::numeric_limits<Int64>::min() || size_t(-n) != numBytes)
      OPENVDB_THROW(RuntimeError, "expected a " << numBytes << "-byte uncompressed " << what
                                                << " chunk, the file declares " << n);
    if (data) is.read(data, -n);
    else is.seekg(-n, std::ios_base::cur);
    return;
  }
  if (!original) OPENVDB_THROW(RuntimeError, "cannot find OpenVDB's own " << what << " chunk reader");
  is.seekg(-8, std::ios_base::cur);
  original(is, data, numBytes);
}
}  // namespace

void bloscFromStream(std::istream& is, char* data, size_t numBytes) {
  static const ReadChunk original = openvdb_function("bloscFromStream");
  checked_chunk(is, data, numBytes, original, "blosc");
}
void unzipFromStream(std::istream& is, char* data, size_t numBytes) {
  static const ReadChunk original = openvdb_function("unzipFromStream");
  checked_chunk(is, data, numBytes, original, "zip");
}

}  // namespace io
}  // namespace OPENVDB_VERSION_NAME
}  // namespace openvdb

namespace pm {

// Make sure openvdb::initialize() was called (idempotent, thread-safe).
void ensure_openvdb_initialized() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

namespace {

const char* const kWho = "read_vdb";

// Metadata we write on every grid and read back (OpenVDB has no notion of
// either): the world frame of the transform, and for integer grids the voxel
// type of the volume written and that it holds labels.
const char* const kFrameKey = "pm_world_frame";
const char* const kTypeKey = "pm_voxel_type";
const char* const kLabelsKey = "pm_labels";

bool is_supported_grid(const openvdb::GridBase& g) {
  return g.isType<openvdb::FloatGrid>() || g.isType<openvdb::DoubleGrid>() || g.isType<openvdb::Int32Grid>() ||
         g.isType<openvdb::Int64Grid>();
}

std::string string_meta(const openvdb::GridBase& g, const char* key) {
  if (const auto m = g.getMetadata<openvdb::StringMetadata>(key)) return m->value();
  return {};
}

// Dense copy of a scalar grid over its active bounding box; inactive voxels
// inside the box (e.g. a level set's far field) take their tree value.
template <class GridT, class T>
Volume dense_volume(const GridT& grid, VoxelType type, const std::string& path) {
  const std::string where = std::string(kWho) + ": " + quote(path);
  // Index coordinates within +-2^30: OpenVDB adds and subtracts them in int
  // (the root's tile and child extents in evalActiveVoxelBoundingBox,
  // CoordBBox::dim() for a box wider than 2^31 voxels, copyToDense's parallel
  // split of min + max; fuzz_vdb, tests/data/regress/vdb-wide-bbox,
  // vdb-far-bbox, vdb-far-root-tile). So every root entry (tile or child,
  // active or not) is checked before any box is computed.
  constexpr std::int64_t kFar = std::int64_t(1) << 30;
  using RootChild = typename GridT::TreeType::RootNodeType::ChildNodeType;
  for (auto it = grid.tree().root().cbeginChildAll(); it; ++it) {
    const openvdb::Coord c = it.getCoord();
    for (int a = 0; a < 3; ++a)
      if (c[a] < -kFar || std::int64_t(c[a]) + RootChild::DIM > kFar)
        throw InputError(where + ": grid " + quote(grid.getName()) + " has a node at index " + std::to_string(c[a]) +
                         " along axis " + std::to_string(a) + "; expected indices in [-2^30, 2^30)");
  }
  const openvdb::CoordBBox bbox = grid.evalActiveVoxelBoundingBox();
  if (bbox.empty()) throw InputError(where + ": grid " + quote(grid.getName()) + " has no active voxels");
  const openvdb::Coord dim = bbox.dim();  // within 2^31 after the check above
  const Dims dims{std::size_t(dim.x()), std::size_t(dim.y()), std::size_t(dim.z())};

  const openvdb::math::Transform& xf = grid.transform();
  if (!xf.isLinear())
    throw InputError(where + ": grid " + quote(grid.getName()) + " has a non-linear transform (" +
                     xf.mapType() + "); expected a linear (affine) one");
  // OpenVDB maps row vectors: world = [i j k 1] * M, so row a of M is the step along axis a.
  const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
  Geometry g;
  for (int a = 0; a < 3; ++a)
    for (int r = 0; r < 3; ++r) g.directions[r][a] = m(a, r);
  const openvdb::Vec3d o = xf.indexToWorld(bbox.min());
  g.origin = {o.x(), o.y(), o.z()};
  check_volume_header(kWho, path, dims, g);

  Volume v(type, dims, g);
  openvdb::tools::Dense<T, openvdb::tools::LayoutXYZ> dense(bbox, v.data<T>());
  openvdb::tools::copyToDense(grid, dense);
  return v;
}

}  // namespace

namespace {

// The frame named by the grid's metadata (we write "LPS"; a file from
// elsewhere has none and is taken as LPS).
void apply_frame(Volume& v, const openvdb::GridBase& grid, const std::string& where) {
  const std::string frame = string_meta(grid, kFrameKey);
  if (frame.empty()) {
    v.set_frame_source({"VDB", "none", "VDB has no world frame: coordinates taken as LPS", false});
  } else if (frame == "LPS") {
    v.set_frame_source({"VDB", "LPS", "", true});
  } else if (frame == "RAS") {
    v.geometry() = with_world_signs(v.geometry(), {-1, -1, 1});
    v.set_frame_source({"VDB", "RAS", "", true});
  } else {
    throw InputError(where + ": grid " + quote(grid.getName()) + " has " + kFrameKey + " " + quote(frame) +
                     "; expected LPS or RAS");
  }
}

// An integer grid's voxels in the voxel type its metadata names (the type of
// the volume that was written), checked to fit it.
template <class T>
Volume integer_volume(Volume v, const openvdb::GridBase& grid, const std::string& where) {
  const std::string name = string_meta(grid, kTypeKey);
  if (name.empty()) return v;
  VoxelType t;
  try {
    t = parse_voxel_type(name);
  } catch (const UsageError&) {
    t = VoxelType::f32;
  }
  if (!is_integer(t))
    throw InputError(where + ": grid " + quote(grid.getName()) + " has " + kTypeKey + " " + quote(name) +
                     "; expected an integer voxel type (uint8 ... int64)");
  if (t == v.type()) return v;
  Volume out(t, v.dims(), v.geometry());
  const T* in = v.data<T>();
  visit_voxel_type(t, [&](auto tag) {
    using U = decltype(tag);
    if constexpr (std::is_integral_v<U>) {
      U* o = out.data<U>();
      for (std::size_t i = 0; i < v.count(); ++i) {
        const std::int64_t x = in[i];
        bool fits;
        if constexpr (std::is_signed_v<U>)
          fits = x >= std::int64_t(std::numeric_limits<U>::min()) && x <= std::int64_t(std::numeric_limits<U>::max());
        else
          fits = x >= 0 && std::uint64_t(x) <= std::uint64_t(std::numeric_limits<U>::max());
        if (!fits) {
          std::ostringstream m;
          m << where << ": grid " << quote(grid.getName()) << " holds " << x << ", outside its "
            << kTypeKey << " " << name << "; expected values of that type";
          throw InputError(m.str());
        }
        o[i] = static_cast<U>(x);
      }
    }
  });
  return out;
}

}  // namespace

Volume openvdb_read(const std::string& path, const std::string& grid_name) {
  const std::string where = std::string(kWho) + ": " + quote(path);
  require_readable(path);
  ensure_openvdb_initialized();
  try {
    // Read through a std::istream that throws on a short read: OpenVDB's own
    // file reader does not check its stream after reading a size field, so a
    // truncated or corrupt file made it allocate an uninitialised size (found
    // by fuzz_vdb; tests/data/regress/vdb-short-read). io::Stream reads the
    // same archives io::File writes.
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(where + ": cannot open");
    in.exceptions(std::ios::failbit | std::ios::badbit);
    openvdb::io::Stream stream(in, /*delayLoad=*/false);
    const openvdb::GridPtrVecPtr grids = stream.getGrids();
    // The named grid, else the first float, double, int32 or int64 grid that
    // is not empty (else the first such grid, whose emptiness is reported).
    openvdb::GridBase::Ptr base, first;
    std::ostringstream found;
    for (const auto& g : *grids) {
      found << (found.tellp() > 0 ? ", " : "") << quote(g->getName()) << " (" << g->type() << ")";
      const bool scalar = is_supported_grid(*g);
      if (!grid_name.empty()) {
        if (g->getName() != grid_name) continue;
        if (!scalar)
          throw InputError(where + ": grid " + quote(grid_name) + " is a " + g->type() +
                           "; expected a float, double, int32 or int64 grid");
        if (!base) base = g;
        continue;
      }
      if (!scalar) continue;
      if (!first) first = g;
      if (!base && !g->empty()) base = g;
    }
    if (!base) base = first;
    if (!base && !grid_name.empty())
      throw InputError(where + ": no grid named " + quote(grid_name) + "; the file has " +
                       (grids->empty() ? std::string("no grids") : found.str()));
    if (!base)
      throw InputError(where + ": no float, double, int32 or int64 grid; the file has " +
                       (grids->empty() ? std::string("no grids") : found.str()));
    const std::string chosen = base->getName();
    Volume v;
    if (auto fg = openvdb::gridPtrCast<openvdb::FloatGrid>(base))
      v = dense_volume<openvdb::FloatGrid, float>(*fg, VoxelType::f32, path);
    else if (auto dg = openvdb::gridPtrCast<openvdb::DoubleGrid>(base))
      v = dense_volume<openvdb::DoubleGrid, double>(*dg, VoxelType::f64, path);
    else if (auto ig = openvdb::gridPtrCast<openvdb::Int32Grid>(base))
      v = integer_volume<std::int32_t>(dense_volume<openvdb::Int32Grid, std::int32_t>(*ig, VoxelType::i32, path),
                                       *base, where);
    else if (auto lg = openvdb::gridPtrCast<openvdb::Int64Grid>(base))
      v = integer_volume<std::int64_t>(dense_volume<openvdb::Int64Grid, std::int64_t>(*lg, VoxelType::i64, path),
                                       *base, where);
    else
      throw InputError(where + ": grid " + quote(chosen) + " is not a float, double, int32 or int64 grid");
    apply_frame(v, *base, where);
    check_volume_header(kWho, path, v.dims(), v.geometry());
    return v;
  } catch (const openvdb::Exception& e) {
    throw InputError(where + ": " + e.what());
  } catch (const std::ios_base::failure&) {
    throw InputError(where + ": truncated or corrupt VDB data (a read went past the end of the file)");
  } catch (const std::bad_alloc&) {
    throw InputError(where + ": corrupt VDB data (a size field asks for more memory than there is)");
  } catch (const std::length_error&) {
    // A container sized from the file beyond max_size() (fuzz_vdb,
    // tests/data/regress/vdb-length-error).
    throw InputError(where + ": corrupt VDB data (a size field is larger than any container can hold)");
  }
}

namespace {

// A grid of ValueT holding `values` (dims d, LayoutXYZ) with background
// values[0]; voxels equal to it are inactive and pruned except the two
// extreme corners, which stay active so the active box keeps the dims.
template <class GridT>
typename GridT::Ptr grid_from_values(std::vector<typename GridT::ValueType>& values, const Dims& d) {
  using ValueT = typename GridT::ValueType;
  const openvdb::Coord lo(0, 0, 0), hi(int(d.nx) - 1, int(d.ny) - 1, int(d.nz) - 1);
  const openvdb::CoordBBox bbox(lo, hi);
  typename GridT::Ptr grid = GridT::create(values.front());
  if constexpr (std::is_integral_v<ValueT>) {
    // copyFromDense compares with a tolerance as |a - b| <= tol, which
    // overflows for labels far apart (signed overflow: undefined, UBSan's
    // VolumeIoRoundTrip.VdbStoresLabelsAsIntegerGridsOfTheSameType): the
    // voxels that differ from the background set one by one instead.
    auto acc = grid->getAccessor();
    const ValueT bg = values.front();
    for (std::size_t k = 0, c = 0; k < d.nz; ++k)
      for (std::size_t j = 0; j < d.ny; ++j)
        for (std::size_t i = 0; i < d.nx; ++i, ++c)
          if (values[c] != bg) acc.setValueOn(openvdb::Coord(int(i), int(j), int(k)), values[c]);
  } else {
    openvdb::tools::Dense<ValueT, openvdb::tools::LayoutXYZ> dense(bbox, values.data());
    openvdb::tools::copyFromDense(dense, *grid, ValueT(0));
  }
  grid->tree().prune();
  grid->tree().setValueOn(lo, values.front());
  grid->tree().setValueOn(hi, values.back());
  return grid;
}

// All voxels as int64 (exact for every integer type).
// \throw InputError for uint64 values above 2^63 - 1.
std::vector<std::int64_t> integer_values(const Volume& v, const std::string& where) {
  std::vector<std::int64_t> out(v.count());
  visit_voxel_type(v.type(), [&](auto tag) {
    using T = decltype(tag);
    if constexpr (std::is_integral_v<T>) {
      const T* p = v.data<T>();
      for (std::size_t i = 0; i < out.size(); ++i) {
        if constexpr (std::is_same_v<T, std::uint64_t>) {
          if (p[i] > std::uint64_t(std::numeric_limits<std::int64_t>::max())) {
            std::ostringstream m;
            m << where << ": voxel " << i << " is " << p[i] << "; expected uint64 values below 2^63 (VDB int64 grid)";
            throw InputError(m.str());
          }
        }
        out[i] = static_cast<std::int64_t>(p[i]);
      }
    }
  });
  return out;
}

}  // namespace

void openvdb_write(const Volume& v, const std::string& path, const std::string& grid_name) {
  const std::string where = "write_vdb: " + quote(path);
  if (v.empty()) throw InputError(where + ": the volume is empty");
  ensure_openvdb_initialized();
  const Dims& d = v.dims();
  const std::size_t limit = std::size_t(1) << 30;  // VDB index coordinates are int32
  if (d.nx > limit || d.ny > limit || d.nz > limit) throw InputError(where + ": volume too large for VDB coordinates");

  // Integer volumes (label maps) become an int32 grid (int64 when a value
  // needs it) with their voxel type and "labels" in the metadata; float and
  // double become a float grid.
  openvdb::GridBase::Ptr grid;
  if (is_integer(v.type())) {
    std::vector<std::int64_t> wide = integer_values(v, where);
    const auto [lo, hi] = std::minmax_element(wide.begin(), wide.end());
    if (*lo >= std::numeric_limits<std::int32_t>::min() && *hi <= std::numeric_limits<std::int32_t>::max()) {
      std::vector<std::int32_t> narrow(wide.begin(), wide.end());
      wide = {};
      grid = grid_from_values<openvdb::Int32Grid>(narrow, d);
    } else {
      grid = grid_from_values<openvdb::Int64Grid>(wide, d);
    }
    grid->insertMeta(kTypeKey, openvdb::StringMetadata(voxel_type_name(v.type())));
    grid->insertMeta(kLabelsKey, openvdb::BoolMetadata(true));
  } else {
    // Exact for float; double is rounded to float.
    std::vector<float> values = v.to_float();
    grid = grid_from_values<openvdb::FloatGrid>(values, d);
  }
  grid->insertMeta(kFrameKey, openvdb::StringMetadata("LPS"));

  const Geometry& g = v.geometry();
  openvdb::Mat4d m = openvdb::Mat4d::identity();
  for (int a = 0; a < 3; ++a)
    for (int r = 0; r < 3; ++r) m(a, r) = g.directions[r][a];
  m(3, 0) = g.origin.x;
  m(3, 1) = g.origin.y;
  m(3, 2) = g.origin.z;
  try {
    grid->setTransform(openvdb::math::Transform::createLinearTransform(m));
    grid->setName(grid_name);
    openvdb::io::File file(path);
    openvdb::GridPtrVec grids{grid};
    file.write(grids);
    file.close();
  } catch (const openvdb::Exception& e) {
    throw IoError(where + ": " + e.what());
  }
}

}  // namespace pm

extern "C" const pm::OpenVdbPlugin* pm_openvdb_plugin() {
  static const pm::OpenVdbPlugin table = [] {
    pm::OpenVdbPlugin t;
    t.read = &pm::openvdb_read;
    t.write = &pm::openvdb_write;
    t.mesh_to_sdf = &pm::openvdb_mesh_to_sdf;
    t.marching_cubes = &pm::openvdb_marching_cubes;
    return t;
  }();
  return &table;
}
