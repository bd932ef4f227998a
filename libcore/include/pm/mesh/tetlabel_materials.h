#pragma once
// Multi-material meshing by labelled Delaunay tetrahedra (SPEC §6.4.3): every
// tetrahedron takes the material with the largest indicator f_i at its
// circumcentre (pm::MaterialSet::argmax); the interfaces are the faces between
// differently labelled tetrahedra, and each material's closed surface is the
// subset of those faces that bound it, so neighbouring materials share their
// triangles exactly (same vertices, opposite orientation).
#include <cstddef>
#include <map>
#include <vector>

#include "pm/field/materials.h"
#include "pm/io/mesh.h"
#include "pm/mesh/tetlabel.h"

namespace pm {

/// The label that fills the outside of `ms`'s domain: the most common material
/// at the domain's 8 corners (ties: the smallest label).
int auto_outside_label(const MaterialSet& ms);

struct MaterialMeshParams {
  /// Label of everything outside the material domain (and of hull faces'
  /// other side); normally the background material (auto_outside_label).
  int outside_label = 0;
  /// Relabel tetrahedra at pinched vertices until every material surface is
  /// a manifold, the outside material's included: pm::make_manifold per
  /// material, then the tetrahedra of a material still pinched at an edge or
  /// vertex join the most common other label there; a few rounds.
  bool repair = true;
  int repair_rounds = 4;
  TetLabelParams label;
};

struct MaterialMeshes {
  /// Every face between two materials, face properties label_a < label_b
  /// (normal from label_a into label_b) and `pair` (index into `pairs`).
  Mesh interfaces;
  std::vector<std::pair<int, int>> pairs;  ///< distinct (label_a, label_b), sorted
  /// Closed, outward-oriented surface of each material other than the
  /// outside label that owns at least one tetrahedron.
  std::map<int, Mesh> surfaces;
  std::map<int, std::size_t> tets_per_label;
  TetLabelStats label_stats;
  std::size_t relabelled = 0;  ///< tetrahedra changed by the manifold repair
  /// Materials whose surface (the outside label's included) is still not a
  /// closed manifold after the repair rounds.
  std::vector<int> nonmanifold_materials;
};

/// Label `tm` by argmax of `ms` at the circumcentres (outside the domain:
/// p.outside_label), repair, and extract the interface and material meshes.
/// Vertex scalar `index` of every mesh is the point's index in tm.points.
MaterialMeshes mesh_materials(TetMesh& tm, const MaterialSet& ms, const MaterialMeshParams& p);

}  // namespace pm
