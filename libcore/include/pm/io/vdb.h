#pragma once
// OpenVDB files: the first FloatGrid or DoubleGrid (or the named one) copied
// densely over its active voxel bounding box; voxels in the box that are
// inactive (a level set's far field) keep their tree value (the background).
// A DoubleGrid gives a double volume. Geometry: the grid's linear transform
// (non-linear ones are rejected), origin = world position of the box's min
// corner, direction of axis a = row a of the affine matrix.
// Writing produces one FloatGrid (every voxel type is converted to float;
// exact for integers below 2^24) with an affine transform from our geometry.
// Its background is the value of voxel (0,0,0); voxels equal to it are made
// inactive and pruned, except the two extreme corners, which stay active so
// the active bounding box - and so the dims - survive a round trip.
#include <string>

#include "pm/base/volume.h"

namespace pm {
/// \throw IoError (missing file), InputError (not a VDB file, no float or
/// double grid, empty grid, non-linear transform, bad geometry).
Volume read_vdb(const std::string& path, const std::string& grid_name = {});
/// \throw IoError on write failure.
void write_vdb(const Volume& v, const std::string& path, const std::string& grid_name = "field");
/// Make sure openvdb::initialize() was called (idempotent, thread-safe).
void ensure_openvdb_initialized();
}  // namespace pm
