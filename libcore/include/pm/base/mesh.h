#pragma once
// Point sets and triangle meshes with named per-vertex scalar properties and
// per-face integer properties. A point set is a Mesh with no faces.
// PolyMesh: triangles and quads (quad-dominant meshes, issue #20).
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

/// Triangles and quads over one vertex list; a triangle has face[3] == -1.
/// Faces are oriented as the triangles they come from.
struct PolyMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 4>> faces;
  std::size_t quad_count() const;
  /// \throw InputError for an index out of range or repeated in a face.
  void validate(const std::string& what) const;
};

/// Set m.normals to the area-weighted average of the normals of the faces
/// around each vertex (unit length; follows the faces' winding). Vertices in
/// no face, or only in degenerate faces, get (0,0,0).
/// \throw InputError when a face index is out of range.
void compute_vertex_normals(Mesh& m);

}  // namespace pm
