#pragma once
// Quality report of a multi-material interface mesh (SPEC §6, Table 6.5):
// a triangle mesh with integer face properties label_a, label_b (the two
// materials each face separates), as `tetlabel --materials` writes it.
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "pm/base/stats.h"
#include "pm/io/mesh.h"
#include "pm/mesh/meshstats.h"

namespace pm {

/// True when `m` has the face properties label_a and label_b.
bool is_interface_mesh(const Mesh& m);

struct InterfaceQuality {
  MeshQuality overall;  ///< every interface face (no self-intersection test: it is non-manifold by design)
  std::size_t edges = 0;
  std::size_t boundary_edges = 0;  ///< edges with one face: holes
  std::size_t junction_edges = 0;  ///< edges with >= 3 faces where >= 3 materials meet (junction curves)
  /// Edges whose faces do not close up every material around them: one face,
  /// or a material met by other than exactly two of the faces (a fold, or a
  /// non-manifold edge of one material's surface).
  std::size_t bad_edges = 0;
  std::size_t self_faces = 0;  ///< faces with label_a == label_b
  std::vector<std::pair<int, int>> pairs;  ///< distinct (min, max) label pairs
  /// Creases (20 degrees) of each interface, the faces of one label pair on their
  /// own: its interior edges are those shared by two of its faces (junction curves
  /// bound an interface and are not counted). overall.crease_share_20 and
  /// overall.interior_edges / creased_edges_20 are these pooled over every interface.
  std::map<std::pair<int, int>, CreaseCount> pair_creases;
  /// Each material's surface: the faces that separate it from another
  /// material, oriented outward (faces are shared exactly with neighbours).
  std::map<int, MeshQuality> materials;
  /// Vertex scalar "junction" present (particles from multiparticles): share
  /// of junction-curve edge endpoints whose junction type is >= 3 (sampled
  /// as a curve or corner particle); -1 when absent or no junction edges.
  double junction_vertex_share = -1;
};

/// Measure an interface mesh. \throw InputError when label_a/label_b are
/// missing or the mesh is invalid.
InterfaceQuality interface_quality(const Mesh& m, const MeshQualityParams& p = {});

/// The outward surface of material `label` taken from an interface mesh
/// (unused vertices dropped; vertex scalar "index" keeps the interface mesh's
/// own "index" when it has one, e.g. the particle index tetlabel writes, else
/// the vertex's index in `m`; other vertex scalars, normals and face
/// properties follow their elements).
Mesh material_from_interfaces(const Mesh& m, int label);

/// JSON: {"overall": {...}, "interfaces": {edges, boundary_edges, junction_edges,
/// bad_edges, self_faces, pairs, crease_share_20, per_pair: [{pair, interior_edges,
/// creased_edges, crease_share_20}], ...}, "materials": {"<label>": {...}}}.
Json to_json(const InterfaceQuality& q);

/// Check requirements on an interface mesh. Keys as check_requirements, where
///  watertight            = no boundary edges and every material surface closed,
///  manifold              = no bad edges and every material surface manifold,
///  no_self_intersections = no material surface self-intersects,
///  labels_consistent     = no face separates a label from itself,
///  rr_min / rr_mean / min_angle thresholds hold overall AND for every material;
///  crease_share_20       = the creases of every interface pooled (overall);
/// other keys (valence6, edge_le_2h, ...) apply to the whole mesh.
/// Returns the failed items. \throw UsageError for an unknown key.
std::vector<std::string> check_interface_requirements(const InterfaceQuality& q, const std::string& requirements);

}  // namespace pm
