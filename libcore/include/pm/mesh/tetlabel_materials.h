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
  /// Sliver spikes: a tetrahedron whose smallest dihedral angle is below
  /// this (degrees), whose own label is on at most one of its four face
  /// neighbours and another label on at least two, takes that label (before
  /// the repair). Such a sliver is a material sheet of no thickness between
  /// two others, all four corners on interfaces, so it stays in every
  /// conforming volume mesh (Chapter 7) whatever the interior points; its
  /// label came from a circumcentre far from it. 0 = off.
  double spike_dihedral = 15;
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
  std::size_t spikes = 0;      ///< sliver spikes relabelled (MaterialMeshParams::spike_dihedral)
  /// Materials whose surface (the outside label's included) is still not a
  /// closed manifold after the repair rounds.
  std::vector<int> nonmanifold_materials;
};

/// MaterialMeshParams::spike_dihedral on labelled tetrahedra: every sliver
/// spike (smallest dihedral angle below min_dihedral degrees, its own label
/// on at most one face neighbour, another label on at least two) takes that
/// other label (ties: the smallest). Decided on the labels as given, then
/// changed together; hull faces count as `outside`. Returns how many changed.
std::size_t relabel_sliver_spikes(TetMesh& tm, int outside, double min_dihedral);

/// Label `tm` by argmax of `ms` at the circumcentres (outside the domain:
/// p.outside_label), repair, and extract the interface and material meshes.
/// Vertex scalar `index` of every mesh is the point's index in tm.points.
MaterialMeshes mesh_materials(TetMesh& tm, const MaterialSet& ms, const MaterialMeshParams& p);

}  // namespace pm
