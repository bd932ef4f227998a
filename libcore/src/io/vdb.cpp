#include "pm/io/vdb.h"

#include <openvdb/io/Compression.h>
#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/math/Transform.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>

#include <dlfcn.h>

#include <cstdint>
#include <fstream>
#include <ios>
#include <limits>
#include <mutex>
#include <new>
#include <sstream>
#include <stdexcept>
#include <string>

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

void ensure_openvdb_initialized() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

namespace {

const char* const kWho = "read_vdb";

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

Volume read_vdb(const std::string& path, const std::string& grid_name) {
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
    openvdb::GridBase::Ptr base;
    std::ostringstream found;
    for (const auto& g : *grids) {
      found << (found.tellp() > 0 ? ", " : "") << quote(g->getName()) << " (" << g->type() << ")";
      const bool scalar = g->isType<openvdb::FloatGrid>() || g->isType<openvdb::DoubleGrid>();
      if (!base && scalar && (grid_name.empty() || g->getName() == grid_name)) base = g;
      if (!grid_name.empty() && g->getName() == grid_name && !scalar)
        throw InputError(where + ": grid " + quote(grid_name) + " is a " + g->type() +
                         "; expected a float or double grid");
    }
    if (!base && !grid_name.empty())
      throw InputError(where + ": no grid named " + quote(grid_name) + "; the file has " +
                       (grids->empty() ? std::string("no grids") : found.str()));
    if (!base)
      throw InputError(where + ": no float or double grid; the file has " +
                       (grids->empty() ? std::string("no grids") : found.str()));
    const std::string chosen = base->getName();
    if (auto fg = openvdb::gridPtrCast<openvdb::FloatGrid>(base))
      return dense_volume<openvdb::FloatGrid, float>(*fg, VoxelType::f32, path);
    if (auto dg = openvdb::gridPtrCast<openvdb::DoubleGrid>(base))
      return dense_volume<openvdb::DoubleGrid, double>(*dg, VoxelType::f64, path);
    throw InputError(where + ": grid " + quote(chosen) + " is not a float or double grid");
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

void write_vdb(const Volume& v, const std::string& path, const std::string& grid_name) {
  const std::string where = "write_vdb: " + quote(path);
  if (v.empty()) throw InputError(where + ": the volume is empty");
  ensure_openvdb_initialized();
  const Dims& d = v.dims();
  const std::size_t limit = std::size_t(1) << 30;  // VDB index coordinates are int32
  if (d.nx > limit || d.ny > limit || d.nz > limit) throw InputError(where + ": volume too large for VDB coordinates");

  // VDB stores float: every voxel type is converted (exact for |integers| < 2^24).
  std::vector<float> values = v.to_float();
  const openvdb::Coord lo(0, 0, 0), hi(int(d.nx) - 1, int(d.ny) - 1, int(d.nz) - 1);
  const openvdb::CoordBBox bbox(lo, hi);
  // Background: the value of voxel (0,0,0), typically the outside value
  // (0 for masks, the far value of a clamped distance field); voxels equal to
  // it become inactive and are pruned away.
  const float background = values.front();
  openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(background);
  {
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(bbox, values.data());
    openvdb::tools::copyFromDense(dense, *grid, 0.0f);
  }
  grid->tree().prune();
  // Keep the full box: the two extreme corners stay active so a reader that
  // takes the active bounding box gets the same dims back.
  grid->tree().setValueOn(lo, values.front());
  grid->tree().setValueOn(hi, values.back());

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
