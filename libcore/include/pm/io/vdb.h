#pragma once
// OpenVDB files: the named grid, else the first FloatGrid, DoubleGrid,
// Int32Grid or Int64Grid that is not empty, copied densely over its active
// voxel bounding box; voxels in the box that are inactive (a level set's far
// field) keep their tree value (the background). A DoubleGrid gives a double
// volume; an integer grid gives the integer voxel type its "pm_voxel_type"
// metadata names (int32 / int64 without it). Geometry: the grid's linear
// transform (non-linear ones are rejected), origin = world position of the
// box's min corner, direction of axis a = row a of the affine matrix; in LPS
// (libcore's frame), or RAS converted when the "pm_world_frame" metadata says
// so; without it the grid is taken as LPS.
// Writing produces one grid with an affine transform from our geometry and
// "pm_world_frame" = "LPS": integer volumes (label maps) an Int32Grid (an
// Int64Grid when a value needs it) with "pm_voxel_type" and "pm_labels" =
// true, so they read back as labels of the same type; float and double
// volumes a FloatGrid. Its background is the value of voxel (0,0,0); voxels
// equal to it are made inactive and pruned, except the two extreme corners,
// which stay active so the active bounding box - and so the dims - survive a
// round trip.
// OpenVDB itself is loaded with the plugin libpmcore_openvdb.so on the first
// call (see src/io/openvdb_plugin.h): tools that never touch a VDB file do
// not pay for loading it.
#include <string>

#include "pm/base/volume.h"

namespace pm {
/// \throw IoError (missing file), InputError (not a VDB file, no float,
/// double, int32 or int64 grid, empty grid, non-linear transform, bad
/// geometry, metadata naming an unknown frame or a type the values do not fit).
Volume read_vdb(const std::string& path, const std::string& grid_name = {});
/// \throw InputError for uint64 values of 2^63 or more; IoError on write failure.
/// Both throw Error when the OpenVDB plugin cannot be loaded.
void write_vdb(const Volume& v, const std::string& path, const std::string& grid_name = "field");
}  // namespace pm
