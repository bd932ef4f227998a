#pragma once
// OFF, OBJ and STL through CGAL's polygon-soup IO (mesh_cgal.cpp, the only
// translation unit that includes CGAL's IO headers); they keep geometry only.
// All write to the given path directly (no atomic rename: write_mesh does that).
#include <string>
#include <vector>

#include "pm/base/mesh.h"
#include "pm/io/frame.h"

namespace pm {

/// OFF (ASCII or binary, as CGAL reads it). Header counts are checked against
/// the file size before anything is allocated.
/// \throw IoError when unreadable, InputError on malformed content.
/// `polygon_sizes`: as pm::mesh_from_polygons gives it.
Mesh read_off(const std::string& path, std::vector<int>* polygon_sizes = nullptr);
/// ASCII OFF, 17 significant digits.
void write_off(const Mesh& m, const std::string& path);

/// Wavefront OBJ: `v` and `f` records (negative indices allowed); normals,
/// texture coordinates, groups and materials are dropped.
Mesh read_obj(const std::string& path, std::vector<int>* polygon_sizes = nullptr);
/// `v` and `f` records only (normals are not written), after a comment line
/// `# frame LPS SPACE=LPS` (or RAS) naming the frame of the coordinates.
void write_obj(const Mesh& m, const std::string& path, WorldFrame frame = WorldFrame::lps);

/// STL, binary or ASCII (detected). Identical corner positions are merged into
/// one vertex. \throw InputError when the file holds no triangle.
Mesh read_stl(const std::string& path);
/// Binary (default; coordinates stored as float) or ASCII STL (17 digits).
/// \throw InputError when the mesh has no faces.
void write_stl(const Mesh& m, const std::string& path, bool binary = true);

}  // namespace pm
