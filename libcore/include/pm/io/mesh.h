#pragma once
// Point sets and triangle (or polygon) meshes with named per-vertex scalar
// properties and per-face integer properties. A point set is a Mesh with no
// faces.
#include <array>
#include <map>
#include <string>
#include <vector>

#include "pm/base/vec.h"

namespace pm {

struct Mesh {
  std::vector<Vec3> vertices;                 ///< #V, world units
  std::vector<Vec3> normals;                  ///< #V or empty
  std::vector<std::array<int, 3>> faces;      ///< #F triangles (vertex indices)
  /// Per-vertex scalar properties, each #V long, written in name order.
  std::map<std::string, std::vector<double>> vertex_scalars;
  /// Per-face integer properties, each #F long.
  std::map<std::string, std::vector<int>> face_ints;

  bool has_normals() const { return !normals.empty(); }
  /// \throw InputError when sizes are inconsistent or a face index is out of range.
  void validate(const std::string& what) const;
};

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

/// Set m.normals to the area-weighted average of the normals of the faces
/// around each vertex (unit length; follows the faces' winding). Vertices in
/// no face, or only in degenerate faces, get (0,0,0).
/// \throw InputError when a face index is out of range.
void compute_vertex_normals(Mesh& m);

}  // namespace pm
