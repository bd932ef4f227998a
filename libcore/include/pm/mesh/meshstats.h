#pragma once
// Quality report for a triangle mesh (SPEC §5 "Quality measures"): radius
// ratio, angles, valence, edge length against a sizing field, topology,
// self-intersections and distance to the isosurface it approximates.
#include <string>
#include <vector>

#include "pm/base/stats.h"
#include "pm/field/field.h"
#include "pm/field/sizing.h"
#include "pm/io/mesh.h"
#include "pm/mesh/topology.h"

namespace pm {

struct QuadQuality;  // pm/mesh/quad_mesh.h

struct MeshQualityParams {
  const ScalarField* field = nullptr;  ///< surface F = iso to measure distances to (optional)
  double iso = 0;
  const SizingField* sizing = nullptr;  ///< target edge length h(x), world units (optional)
  bool self_intersections = true;       ///< run CGAL's self-intersection test (manifold meshes only)
};

struct MeshQuality {
  std::size_t vertices = 0, faces = 0;
  // Radius ratio 2 r_in / r_circ: 1 equilateral, 0 degenerate.
  double rr_min = 0, rr_mean = 0;
  std::vector<std::size_t> rr_histogram;  ///< 10 bins over [0, 1]
  double min_angle_deg = 0, max_angle_deg = 0;
  // Valence (number of edge neighbours) over vertices used by faces.
  std::vector<std::size_t> valence_histogram;  ///< index = valence (capped at 15)
  double valence6_share = 0, valence_outside_5_7_share = 0;
  // Edge length / h (mean of h at the endpoints); only with a sizing field.
  bool has_sizing = false;
  double edge_h_max = 0, edge_h_mean = 0, edge_le_2h_share = 0;
  // Distance to the isosurface (Newton projection), world units; only with a field.
  bool has_field = false;
  double dist_vertex_max = 0, dist_vertex_mean = 0, dist_centroid_max = 0, dist_centroid_mean = 0;
  std::size_t dist_failed = 0;  ///< points whose projection did not converge (left out of the above)
  MeshTopology topology;
  int self_intersecting_pairs = -1;  ///< -1: not tested (non-manifold mesh or disabled)
  double edge_length_mean = 0;
  // Smoothness: interior edges (exactly two faces) whose faces bend by more than
  // 20 degrees (angle between the normals, orientation made consistent across the
  // edge). Slice terraces of anisotropic scans show here, not in the radius ratio.
  std::size_t interior_edges = 0, creased_edges_20 = 0;
  double crease_share_20 = 0;  ///< creased_edges_20 / interior_edges (0 without interior edges)
};

/// Interior edges and creases of a set of faces of a mesh.
struct CreaseCount {
  std::size_t interior_edges = 0;  ///< edges shared by exactly two of the faces (both non-degenerate)
  std::size_t creased = 0;         ///< of those, the ones whose faces bend by more than the angle
  double share() const { return interior_edges ? double(creased) / double(interior_edges) : 0.0; }
};

/// Count creases among `faces` (indices into m.faces; empty = every face): an
/// edge shared by exactly two of them is interior; it is creased when the angle
/// between the two face normals exceeds `angle_deg` degrees. When the two faces
/// run through the edge in the same direction (inconsistent orientation) one
/// normal is flipped first, so the bend does not depend on orientation. Edges
/// with a zero-area face are left out. A flat fan has no creases; a cube
/// triangulated into 12 triangles has 18 interior edges, 12 of them creased (90°).
CreaseCount count_creases(const Mesh& m, const std::vector<int>& faces = {}, double angle_deg = 20);

MeshQuality mesh_quality(const Mesh& m, const MeshQualityParams& p = {});

/// JSON object with every measure (keys as in MeshQuality, topology nested).
Json to_json(const MeshQuality& q);

/// Check `requirements`, a comma-separated list such as
/// "rr_min>=0.3,rr_mean>=0.94,valence6>=0.65,crease_share_20<=0.03,watertight,manifold,genus=0,
/// no_self_intersections".
/// With `quads` (a polygon mesh's pm::quad_quality) also quad_share,
/// corner_share_70_110, valence4_share and jacobian_min.
/// Returns the failed ones (empty = all met). \throw UsageError for an unknown key.
std::vector<std::string> check_requirements(const MeshQuality& q, const std::string& requirements,
                                            const QuadQuality* quads = nullptr);

/// Number of intersecting pairs of non-adjacent triangles (CGAL Polygon Mesh
/// Processing); -1 when the mesh is not a manifold polygon mesh.
int count_self_intersections(const Mesh& m);
/// The intersecting pairs of non-adjacent triangles as face indices of `m`;
/// false (and no pairs) when the mesh is not a manifold polygon mesh.
/// `known_polygon_mesh`: the caller guarantees that it is one (e.g. edge
/// flips and vertex moves of a mesh that was checked), so CGAL's soup check,
/// about a third of the cost, is skipped.
bool self_intersecting_faces(const Mesh& m, std::vector<std::pair<int, int>>& out, bool known_polygon_mesh = false);
namespace detail {
/// The same by CGAL's own PMP::self_intersections (its box search), for the
/// test that holds self_intersecting_faces to it pair for pair.
bool cgal_self_intersecting_faces(const Mesh& m, std::vector<std::pair<int, int>>& out);
}  // namespace detail
/// Intersecting pairs of non-adjacent triangles of an interface mesh (face
/// properties `label_a`, `label_b`), tested on each material's closed surface
/// in turn (the faces with label L on one side: L's surface meets itself or
/// crosses a neighbour there); pairs as sorted, unique face indices of `m`.
/// A material whose surface is not a manifold polygon mesh (e.g. two parts
/// touching at a vertex) cannot be tested by CGAL: it is skipped and, when
/// `untested` is given, appended to it.
/// \throw std::out_of_range when `m` lacks label_a or label_b.
std::vector<std::pair<int, int>> material_self_intersections(const Mesh& m, const std::vector<int>& materials,
                                                             std::vector<int>* untested = nullptr);

}  // namespace pm
