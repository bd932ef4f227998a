#pragma once
// Writing quad-dominant polygon meshes (pm::PolyMesh, issue #20) with the
// quads kept as quads: PLY (binary or ASCII, `vertex_indices` lists of 3 or
// 4), Wavefront OBJ and OFF, by extension. STL and the other triangle-only
// formats are refused. Atomic (temporary file + rename); the file states the
// frame (PLY and OBJ comments), as write_mesh does.
#include <string>

#include "pm/io/frame.h"
#include "pm/base/mesh.h"

namespace pm {

/// True for .ply .obj .off.
bool is_poly_mesh_path(const std::string& path);
/// ".ply .obj .off", for messages and help.
std::string poly_mesh_extensions();

/// \throw UsageError for another extension (STL: triangles only), InputError
/// when the mesh fails validate(), IoError when the file cannot be written.
void write_poly_mesh(const PolyMesh& m, const std::string& path, WorldFrame frame = WorldFrame::lps,
                     bool binary = true);

}  // namespace pm
