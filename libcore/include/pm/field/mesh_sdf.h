#pragma once
// Signed distance volume of a closed triangle mesh via OpenVDB's
// mesh-to-level-set conversion.
#include "pm/base/volume.h"
#include "pm/io/mesh.h"

namespace pm {

struct MeshSdfParams {
  double voxel = 0;   ///< voxel size, world units (> 0)
  double band = 0;    ///< narrow band half-width, voxels; 0 = exact distance everywhere in the box
  double padding = 4; ///< voxels added around the mesh's bounding box
};

struct MeshCheck {
  std::size_t boundary_edges = 0;     ///< edges with one face
  std::size_t nonmanifold_edges = 0;  ///< edges with more than two faces
  bool closed() const { return boundary_edges == 0 && nonmanifold_edges == 0; }
};

/// Count boundary and non-manifold edges of a triangle mesh.
MeshCheck check_closed(const Mesh& m);

/// The grid mesh_to_sdf samples: the mesh's bounding box plus the padding
/// (and a voxel when banded), on multiples of the voxel size.
struct MeshSdfGrid {
  Dims dims;
  Vec3 origin;
};
/// \throw UsageError (voxel, band, padding), InputError (no faces, not
/// closed, a non-finite vertex, a grid of more than 2^31 voxels).
MeshSdfGrid mesh_sdf_grid(const Mesh& m, const MeshSdfParams& p);

/// Dense float signed distance volume (negative inside, world units) over the
/// mesh's bounding box plus padding, axis-aligned with spacing `voxel`.
/// Outside the band (band > 0) values are clamped to ±band·voxel.
/// \throw InputError when the mesh has no faces, is not closed (says how many
/// boundary / non-manifold edges), or the grid would exceed 2^31 voxels;
/// UsageError when voxel <= 0 or band < 0.
Volume mesh_to_sdf(const Mesh& m, const MeshSdfParams& p);

}  // namespace pm
