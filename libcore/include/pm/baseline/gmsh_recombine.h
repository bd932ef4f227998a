#pragma once
// The quad baseline of issue #20: Gmsh's recombination of a triangle surface
// into quads (Blossom perfect matching by default), run through Gmsh's C API
// (Debian's libgmsh-dev, loaded on first use) on our own triangles, so that a
// quad packing and Gmsh's quads share their vertices. World units.
#include <cstddef>
#include <string>

#include "pm/base/mesh.h"

namespace pm {

struct GmshRecombineParams {
  /// Gmsh's Mesh.RecombinationAlgorithm: 0 simple (greedy), 1 Blossom
  /// (minimum-cost perfect matching), 2 simple full-quad, 3 Blossom full-quad.
  /// The full-quad variants subdivide and so change the vertices.
  int algorithm = 1;
  /// Gmsh's Mesh.RecombineOptimizeTopology: passes of topological clean-up
  /// after recombination. They add, remove and move vertices; 0 keeps the
  /// input's vertices, for a comparison at the same vertex count.
  int optimize_topology = 0;
};

struct GmshRecombineResult {
  PolyMesh mesh;               ///< quads and the triangles left, vertices in Gmsh's output order
  std::size_t input_vertices = 0;
  double seconds = 0;          ///< time in Gmsh (model set-up, recombination, read-back)
  std::string gmsh_version;
};

/// Recombines the triangles of `tri` with Gmsh. Deterministic for a given
/// Gmsh version. Not thread-safe (Gmsh keeps one global model).
/// \throw InputError when `tri` is not a valid triangle mesh or has no faces,
/// IoError when Gmsh fails (its message included).
GmshRecombineResult gmsh_recombine(const Mesh& tri, const GmshRecombineParams& p = {});

}  // namespace pm
