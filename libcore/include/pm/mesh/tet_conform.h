#pragma once
// Conforming labelled tetrahedral meshes (issue #19, SPEC §7 "Volume
// packing"): the constrained Delaunay tetrahedralisation (TetGen -p) of a
// closed surface, or of the interfaces between several materials, plus given
// interior points; then TetGen's quality refinement (-q) and its sliver
// removal (-O: edge/face flips and vertex smoothing), each as its own pass on
// the previous mesh (-r) and measured with pm::tet_quality. The boundary is
// kept exactly (-Y, no Steiner point on a boundary triangle): the result's
// boundary and interface faces are the input triangles, on the input
// vertices. Every region TetGen finds between the triangles (-A) takes one
// material by a volume-weighted vote of `label_at` at its tetrahedra's
// centroids; regions of the outside label (cavities) are dropped. World units.
#include <array>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "pm/base/mesh.h"
#include "pm/base/stats.h"
#include "pm/base/vec.h"
#include "pm/io/tet_mesh.h"
#include "pm/mesh/tet_quality.h"

namespace pm {

struct ConformParams {
  /// Quality refinement (TetGen -q): tetrahedra with a dihedral angle below
  /// `min_dihedral` (degrees) or a circumradius/shortest-edge ratio above
  /// `radius_edge` are split by a Steiner point inside the volume. The bound
  /// is a target, not a guarantee: next to the kept boundary a split point
  /// may be refused, and sliver removal afterwards lowers the smallest angle
  /// a little (brain: 18 -> 12.5° after removal, 12 -> 8.3°; hence 18 for
  /// the 12). min_dihedral = 0: no refinement step.
  double min_dihedral = 18;
  double radius_edge = 2.0;  ///< > 1 (TetGen terminates for >= √2 in theory)
  /// Refinement also splits tetrahedra larger than this, world units³ (TetGen
  /// -a; 0 = no bound): how TetGen alone reaches a given vertex count.
  double max_volume = 0;
  /// Sliver removal (TetGen -O, level `optimise_level` 1..9, scheme 7: flips,
  /// smoothing of interior vertices, point insertion): TetGen works on every
  /// tetrahedron whose largest dihedral angle exceeds `max_dihedral`
  /// (degrees, in (90, 180)); its smoothing and point insertion use the same
  /// bound. Boundary vertices never move.
  bool optimise = true;
  double max_dihedral = 140;
  int optimise_level = 9;
  /// Rounds of refinement + sliver removal (1 to 5); a round after the first
  /// runs only when the previous one left a dihedral angle below
  /// min_dihedral. Its steps are named "refine 2", "optimise 2", ... On the
  /// brain (min_dihedral 12) a second round took the smallest angle from
  /// 8.3° only to 8.8° and the largest from 147° to 153°: off by default.
  int rounds = 1;
  /// Interior points closer than this to a boundary triangle (TetGen would
  /// split the triangle) or to an earlier interior point are dropped
  /// (relative to the boundary's bounding-box diagonal; > 0). Points merely
  /// close to the boundary are boundary_clearance's.
  double point_tolerance = 1e-6;
  /// Interior points closer to a boundary triangle than this times the
  /// triangle's longest edge are dropped before meshing: TetGen keeps the
  /// boundary (-Y), so such a point makes a flat tetrahedron on it that
  /// neither refinement nor smoothing repairs (0 = keep them). At 0.2 the
  /// face angle of a tetrahedron on an equilateral triangle with its apex that
  /// high is above 34°.
  double boundary_clearance = 0.2;
  /// Each meshing (TetGen's steps, then the smoothing below) is checked for
  /// tetrahedra with a dihedral angle below exude_below or above exude_above
  /// (degrees). When some are left, the interior points (not boundary
  /// vertices or Steiner points) of the tetrahedra TetGen left outside that
  /// band are removed and the volume is meshed again, up to exude_rounds
  /// times (0 = never). Brain mask: none left, one meshing; nested head: 11
  /// left (0.9..178°), 376 points removed, 15.7..146° after the second.
  int exude_rounds = 1;
  double exude_below = 12, exude_above = 160;
  /// Of the meshings (1 + exude rounds), the one with the fewest tetrahedra
  /// outside [exude_below, exude_above] is kept. ODT smoothing and sliver
  /// perturbation of the interior and Steiner points (pm::odt_smooth;
  /// boundary vertices fixed) end each meshing, this many sweeps (0 = none),
  /// measured as step "smooth" ("smooth 2", ...).
  int smooth_sweeps = 5;
  bool progress = true;  ///< one pm::info line per step
};

/// One measured step: "cdt" (boundary + interior points), "refine",
/// "optimise" (then "refine 2", "optimise 2" when a second round runs),
/// "smooth"; a meshing again after removing points adds "cdt 2" ... "smooth 2";
/// "keep ..." repeats the step whose mesh is returned when it is not the last.
struct ConformStep {
  std::string name;
  double seconds = 0;                                      ///< TetGen's pass (wall clock), without the measurement
  std::size_t vertices = 0, tets = 0, steiner_points = 0;  ///< of the labelled (kept) tetrahedra
  TetQuality quality;
  /// Share of tetrahedra with all 6 dihedral angles in [25°, 140°] (the target band).
  double share_25_140 = 0;
};

struct ConformResult {
  /// Vertices: the boundary vertices used by triangles (input order), then
  /// the interior points kept (input order), then Steiner points. Tetrahedra
  /// positively oriented, materials from the vote; triangles and their label
  /// pairs as given (renumbered only when unused boundary vertices were dropped).
  LabelledTets mesh;
  std::vector<ConformStep> steps;
  std::size_t steiner_points = 0;            ///< vertices TetGen added (all inside the volume)
  std::size_t regions = 0;                   ///< regions TetGen found between the triangles
  std::size_t dropped_regions = 0;           ///< voted outside_label: not meshed (cavities)
  std::size_t split_vote_regions = 0;        ///< regions whose tetrahedra did not all vote alike
  /// The smallest share of a region's volume that voted for its label (1 =
  /// unanimous; near 1 when only tetrahedra at the surface voted otherwise).
  double min_vote_share = 1;
  std::size_t unused_boundary_vertices = 0;  ///< in no triangle: left out
  std::size_t interior_given = 0, interior_kept = 0;
  std::size_t interior_exuded = 0;  ///< interior points removed to mesh again (exude_rounds)
  std::string kept_step;            ///< the meshing kept (its last TetGen step's name)
  std::size_t smooth_moves = 0;     ///< vertex moves of the ODT smoothing
  std::size_t interior_outside = 0;     ///< label_at gave outside_label
  std::size_t interior_near_point = 0;  ///< within the tolerance of a boundary triangle or an earlier point
  std::size_t interior_near_boundary = 0;  ///< closer to a boundary triangle than boundary_clearance
  std::size_t interior_refused = 0;     ///< not kept by TetGen (outside the surface, on a triangle)
  /// Materials whose surface is not a manifold polygon mesh (parts touching
  /// at a vertex), so that the self-intersection test could not run on them.
  std::vector<int> self_intersection_untested;
};

/// Mesh the volume bounded by `boundary` (vertices + triangles, world units;
/// normals and properties ignored) with `interior` points inside.
/// `triangle_labels`: #F (a, b), a < b, the materials on the two sides of
/// each triangle (one surface: all (outside, inside)). `label_at` gives the
/// material at a point; `outside_label` is the outside (and cavities).
/// `what` names the boundary in messages.
/// Preconditions checked before meshing (InputError with counts): finite
/// coordinates, valid and distinct indices, no zero-area or repeated
/// triangle, no two vertices at one position, labels a < b; closed: with one
/// label pair every edge in exactly 2 triangles, with several every edge in
/// at least 2 and, for each material, in an even number of the triangles
/// that have it on one side; no self-intersection (CGAL, per material).
/// \throw UsageError for bad parameters; InputError for bad input, for a
/// TetGen failure (naming the step and TetGen's reason) and when a step's
/// boundary/interface faces are not the input triangles or their labels
/// disagree with the materials on their sides.
ConformResult conforming_tets(const Mesh& boundary, const std::vector<std::array<int, 2>>& triangle_labels,
                              const std::vector<Vec3>& interior, const std::function<int(const Vec3&)>& label_at,
                              int outside_label, const ConformParams& p = {}, const std::string& what = "boundary");

/// Counts, and per step seconds, vertices, tetrahedra and pm::to_json(TetQuality)
/// (plus share_25_140), for --stats.
Json to_json(const ConformResult& r);

/// The tetrahedra of m with a dihedral angle outside [below, above]
/// degrees: their count, and in `remove` (sorted, when given) the vertices
/// in [first, last) (the interior points) that the next meshing should do
/// without: those of the bad tetrahedra, and for a bad tetrahedron with none
/// (boundary vertices and Steiner points only) those of every tetrahedron
/// around its vertices, so that the next meshing differs there.
std::size_t tets_outside_band(const LabelledTets& m, std::size_t first, std::size_t last, double below, double above,
                              std::vector<std::size_t>* remove = nullptr);
/// The steps alone: name, seconds, vertices, tetrahedra, Steiner points, quality.
Json to_json(const std::vector<ConformStep>& steps);

}  // namespace pm
