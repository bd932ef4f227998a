#pragma once
// Quality of a labelled tetrahedral mesh (issue #19, SPEC §7): dihedral
// angles, radius ratio ρ = 3 r_in / r_circ (1 for the regular tetrahedron,
// 0 for a flat one), volume, orientation, per material and overall, and the
// checks a solver needs: every tetrahedron positively oriented, the outer
// boundary a manifold, and the file's boundary/interface triangles equal to the
// faces where the tetrahedra's material changes. World units.
#include <array>
#include <map>
#include <string>
#include <vector>

#include "pm/base/stats.h"
#include "pm/io/tet_mesh.h"

namespace pm {

struct TetStats {
  std::size_t tets = 0;
  double volume = 0;                    ///< sum of |volumes|, world units³
  double dihedral_min = 180, dihedral_max = 0;  ///< degrees
  double rr_min = 1, rr_mean = 0;
  std::size_t under_10 = 0;             ///< tetrahedra with a dihedral angle below 10°
  std::size_t within_25_140 = 0;        ///< tetrahedra whose 6 dihedral angles all lie in [25°, 140°]
  std::size_t non_positive = 0;         ///< tetrahedra with volume <= 0 (inverted or flat)
  std::array<std::size_t, 18> dihedral_hist{};  ///< all 6 angles of each tetrahedron, 10° bins
  std::array<std::size_t, 10> rr_hist{};        ///< radius ratio, bins of 0.1
  double share_under_10() const { return tets ? double(under_10) / double(tets) : 0.0; }
  double share_25_140() const { return tets ? double(within_25_140) / double(tets) : 0.0; }
};

struct TetQuality {
  std::size_t vertices = 0;
  TetStats overall;
  std::map<int, TetStats> materials;
  std::size_t boundary_faces = 0;   ///< faces of one tetrahedron only (the outer boundary)
  std::size_t interface_faces = 0;  ///< faces between two tetrahedra of different materials
  /// Outer-boundary edges not shared by exactly two boundary faces (a
  /// boundary is always closed: edges have an even count; 4 or more is a
  /// non-manifold edge, where two parts of the mesh touch along an edge).
  std::size_t boundary_nonmanifold_edges = 0;
  std::size_t overfull_faces = 0;   ///< faces of three or more tetrahedra (not a valid mesh)
  /// When the mesh lists triangles: do they equal the boundary and interface
  /// faces (as sets of vertex triples)? `triangles_missing` faces are not
  /// listed, `triangles_extra` listed triangles are no such face.
  bool has_triangles = false;
  std::size_t triangles_missing = 0, triangles_extra = 0;
};

/// Dihedral angles (degrees) at the 6 edges of tetrahedron abcd, in the order
/// ab, ac, ad, bc, bd, cd; radius ratio 3 r_in / r_circ (0 when flat).
std::array<double, 6> tet_dihedrals(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
double tet_radius_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// The smallest and largest of the six dihedral angles (degrees), as
/// tet_dihedrals would give them, with two arc cosines instead of six: the
/// angle grows with the cosine of the two faces' outward normals.
struct DihedralRange {
  double min = 0, max = 0;
};
DihedralRange tet_dihedral_range(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Quality of every tetrahedron and the face checks; parallel over the
/// tetrahedra (TBB), with the same numbers, bit for bit, for any thread count.

TetQuality tet_quality(const LabelledTets& t);
Json to_json(const TetQuality& q);
/// A short table for stderr.
std::string format_table(const TetQuality& q);
/// --require items that fail: positive, boundary_manifold, triangles_match,
/// KEY>=V / KEY<=V / KEY=V / KEY>V / KEY<V on the overall numbers, KEY one of
/// dihedral_min dihedral_max (degrees; also spelt min_dihedral max_dihedral),
/// rr_min rr_mean, share_under_10 share_25_140 (fractions 0..1). A failed
/// item comes back with the value found: "dihedral_min>=12 (have 0.06)".
/// \throw UsageError for an unknown item or a malformed value.
std::vector<std::string> check_tet_requirements(const TetQuality& q, const std::string& requirements);

}  // namespace pm
