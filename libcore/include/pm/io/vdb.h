#pragma once
// OpenVDB files: the first FloatGrid (or the named one) sampled densely over
// its active bounding box, with its linear transform as geometry. Writing
// produces a FloatGrid; with `background` set, voxels equal to it are inactive.
#include <string>

#include "pm/base/volume.h"

namespace pm {
Volume read_vdb(const std::string& path, const std::string& grid_name = {});
void write_vdb(const Volume& v, const std::string& path, const std::string& grid_name = "field");
/// Make sure openvdb::initialize() was called (idempotent, thread-safe).
void ensure_openvdb_initialized();
}  // namespace pm
