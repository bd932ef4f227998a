#pragma once
// Topology of triangle meshes (boundary and non-manifold edges, components, genus).
#include <cstddef>

#include "pm/base/mesh.h"

namespace pm {

/// Topology of a triangle mesh: boundary and non-manifold edges, connected
/// components, Euler characteristic and genus (for closed orientable manifolds).
struct MeshTopology {
  std::size_t vertices = 0, edges = 0, faces = 0;
  std::size_t boundary_edges = 0, nonmanifold_edges = 0, nonmanifold_vertices = 0;
  std::size_t components = 0;
  long euler = 0;  ///< V - E + F over the used vertices
  long genus = 0;  ///< (2·components - euler) / 2 when closed and manifold, else -1
  bool closed_manifold() const { return boundary_edges == 0 && nonmanifold_edges == 0 && nonmanifold_vertices == 0; }
};
MeshTopology mesh_topology(const Mesh& m);

/// A closed manifold (every edge in two triangles, every vertex one fan)
/// whose triangles are oriented consistently (no directed edge twice): a
/// polygon mesh for CGAL, without CGAL's slower polygon-soup test.
bool closed_oriented_manifold(const Mesh& m);

}  // namespace pm
