#pragma once
// Per-format mesh readers and writers behind pm::read_mesh / pm::write_mesh.
// OFF, OBJ and STL go through CGAL's polygon-soup IO (mesh_cgal.cpp, the only
// translation unit that includes CGAL's IO headers); they keep geometry only.
// All write to the given path directly (no atomic rename: write_mesh does that).
#include <cstddef>
#include <string>
#include <vector>

#include "pm/base/vec.h"
#include "pm/io/mesh.h"

namespace pm {

/// A Mesh from a polygon soup: polygons (each a list of vertex indices, at
/// least 3) are fan-triangulated (v0 v1 v2, v0 v2 v3, ...).
/// \throw InputError "fn: "path": polygon i ..." when a polygon has fewer than
/// 3 vertices or an index >= points.size().
Mesh mesh_from_polygons(std::vector<Vec3> points, const std::vector<std::vector<std::size_t>>& polygons,
                        const std::string& fn, const std::string& path);

/// OFF (ASCII or binary, as CGAL reads it). Header counts are checked against
/// the file size before anything is allocated.
/// \throw IoError when unreadable, InputError on malformed content.
Mesh read_off(const std::string& path);
/// ASCII OFF, 17 significant digits.
void write_off(const Mesh& m, const std::string& path);

/// Wavefront OBJ: `v` and `f` records (negative indices allowed); normals,
/// texture coordinates, groups and materials are dropped.
Mesh read_obj(const std::string& path);
/// `v` and `f` records only (normals are not written).
void write_obj(const Mesh& m, const std::string& path);

/// STL, binary or ASCII (detected). Identical corner positions are merged into
/// one vertex. \throw InputError when the file holds no triangle.
Mesh read_stl(const std::string& path);
/// Binary (default; coordinates stored as float) or ASCII STL (17 digits).
/// \throw InputError when the mesh has no faces.
void write_stl(const Mesh& m, const std::string& path, bool binary = true);

}  // namespace pm
