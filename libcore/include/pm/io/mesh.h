#pragma once
// Reading and writing meshes and point sets (the Mesh type: pm/base/mesh.h).
#include <array>
#include <map>
#include <string>
#include <vector>

#include "pm/base/mesh.h"
#include "pm/base/vec.h"

namespace pm {

struct MeshWriteParams {
  bool binary = true;  ///< PLY/STL: binary (default) or ASCII
};

/// Read by extension: .ply (ASCII / binary little and big endian; vertex
/// properties x y z, optional nx ny nz, any other scalar property; face
/// vertex_indices/vertex_index lists (polygons are fan-triangulated) and
/// integer face properties), .off, .obj, .stl.
/// \throw IoError, InputError naming the file, the problem and the expectation;
/// UsageError for an unknown extension.
Mesh read_mesh(const std::string& path);

/// Write by extension (.ply keeps every property: xyz, normals and vertex
/// scalars as float, face properties as int; .off/.obj/.stl keep geometry only).
/// Atomic (temporary file + rename).
/// \throw UsageError for an unknown extension (expected .ply .off .obj .stl),
/// InputError when the mesh fails validate() or cannot be stored in the format,
/// IoError when the file cannot be written.
void write_mesh(const Mesh& m, const std::string& path, const MeshWriteParams& p = {});

/// PLY only, to/from an already chosen path (no atomic rename): used by tests and fuzzers.
/// read_ply accepts every PLY scalar type; other elements than vertex and face
/// are skipped. write_ply writes binary little endian or ASCII.
Mesh read_ply(const std::string& path);
void write_ply(const Mesh& m, const std::string& path, bool binary = true);


}  // namespace pm
