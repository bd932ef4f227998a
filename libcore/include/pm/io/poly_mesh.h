#pragma once
// Writing quad-dominant polygon meshes (pm::PolyMesh, issue #20) with the
// quads kept as quads: PLY (binary or ASCII, `vertex_indices` lists of 3 or
// 4), Wavefront OBJ and OFF, by extension. STL and the other triangle-only
// formats are refused. Atomic (temporary file + rename); the file states the
// frame (PLY and OBJ comments), as write_mesh does.
#include <string>
#include <vector>

#include "pm/io/frame.h"
#include "pm/base/mesh.h"

namespace pm {

/// True for .ply .obj .off.
bool is_poly_mesh_path(const std::string& path);
/// ".ply .obj .off", for messages and help.
std::string poly_mesh_extensions();

/// Regroups a fan-triangulated mesh (as the readers give it, with each input
/// polygon's vertex count in `polygon_sizes`) into its triangles and quads.
/// \throw InputError naming `what` when a polygon has more than 4 vertices or
/// the sizes do not add up to the triangles.
PolyMesh fans_to_polygons(const Mesh& tri, const std::vector<int>& polygon_sizes, const std::string& what);

/// Reads a triangle/quad mesh from .ply .obj .off with its quads kept
/// (`frame`: as read_ply sets it; OBJ and OFF: LPS).
/// \throw UsageError for another extension; IoError / InputError as the
/// readers, and for polygons of more than 4 vertices.
PolyMesh read_poly_mesh(const std::string& path, WorldFrame* frame = nullptr);

/// As read_mesh (frame converted to LPS, properties kept), and each face's
/// polygon: `polygon_sizes` gets the vertex count of every polygon of a .ply
/// .obj .off file in file order, its fan triangles (v0, vk, vk+1) being
/// consecutive faces; other formats give triangles only (all 3).
Mesh read_mesh_polygons(const std::string& path, std::vector<int>& polygon_sizes);

/// \throw UsageError for another extension (STL: triangles only), InputError
/// when the mesh fails validate(), IoError when the file cannot be written.
void write_poly_mesh(const PolyMesh& m, const std::string& path, WorldFrame frame = WorldFrame::lps,
                     bool binary = true);

}  // namespace pm
