#pragma once
// Local improvement of a closed triangle mesh that samples an implicit
// surface F = iso (the surface tetlabel extracts from the particles):
// valence- and quality-driven edge flips, then tangential smoothing with
// every moved vertex projected back onto F = iso. Topology is kept (a flip
// never creates a duplicate edge; no vertex is added or removed) and no move
// or flip may fold a triangle, so a closed manifold stays one; where a change
// makes triangles intersect (thin parts), the vertices around it are frozen
// and the improvement is redone (checked with CGAL).
//
// Why: the Delaunay surface of a converged particle system is already good
// (radius ratio mean ~0.94), but a few triangles around particles that did
// not settle (sizing-field gradients, thin parts) are poor, and about a third
// of the vertices have a valence other than 6. A few flips and relaxation
// steps fix both while every vertex stays on the isosurface.
#include <cstddef>

#include "pm/field/field.h"
#include "pm/field/materials.h"
#include "pm/io/mesh.h"

namespace pm {

struct SurfaceImproveParams {
  int rounds = 3;              ///< rounds of (flip passes, smoothing steps); 0 = nothing
  int smoothing_steps = 2;     ///< tangential smoothing steps per round
  double smoothing = 0.5;      ///< fraction of the way to the area-weighted centroid of the 1-ring
  /// A flip may not lower the pair's smaller radius ratio below this fraction
  /// of what it was nor below min(what it was, 0.5) (valence flips), and must
  /// raise it by this factor (quality flips of pairs below `poor`); moves obey
  /// the same min(old, 0.5) floor, so the worst radius ratio of the mesh ends
  /// >= min(its start, 0.5).
  double keep_quality = 0.8, quality_gain = 1.1, poor = 0.5;
  double max_fold_deg = 30;    ///< a flip or move may turn a triangle's normal by at most this much
  int newton_steps = 6;        ///< projection onto F = iso after a move
  double tolerance = 1e-6;     ///< |F - iso| accepted after projection, relative to the mean edge length
  /// The input's triangles are known not to cross (faces of one valid
  /// tetrahedralization, as tetlabel's): the check of the input is skipped
  /// and self_intersections_before is 0.
  bool input_embedded = false;
};

struct SurfaceImproveStats {
  std::size_t flips = 0;           ///< edge flips applied
  std::size_t moves = 0;           ///< vertex moves applied (over all steps)
  std::size_t rejected_moves = 0;  ///< moves refused (fold or failed projection)
  std::size_t unfolded = 0;        ///< moves that turned an inverted triangle back (counted in moves)
  double rr_min_before = 0, rr_mean_before = 0, rr_min_after = 0, rr_mean_after = 0;
  double valence6_before = 0, valence6_after = 0;  ///< share of vertices with 6 neighbours
  /// Intersecting pairs of non-adjacent triangles before and after (CGAL);
  /// vertices where flips (and, if that was not enough, moves) were
  /// switched off because they made triangles cross.
  std::size_t self_intersections_before = 0, self_intersections = 0, frozen = 0;
};

/// Improve `mesh` in place (vertices, faces; normals are recomputed from ∇F
/// when present; vertex and face properties follow their elements, which keep
/// their indices). The mesh must be a closed, consistently oriented manifold.
/// \throw InputError when it is not (boundary or non-manifold edges).
SurfaceImproveStats improve_surface(Mesh& mesh, const ScalarField& field, double iso,
                                    const SurfaceImproveParams& p = {});

/// The same for the interface mesh of several materials (face properties
/// label_a, label_b as tetlabel --materials writes them): a vertex inside one
/// interface moves on it (f_a = f_b, projected with Newton on f_a - f_b); a
/// vertex on a junction curve or corner (several interfaces, or an edge with
/// other than two triangles) stays; only edges inside one interface flip.
/// Crossings are checked on every material's closed surface. Valence shares
/// count the interface vertices only.
/// \throw InputError without label_a/label_b or with labels not in `ms`.
SurfaceImproveStats improve_interfaces(Mesh& interfaces, const MaterialSet& ms, const SurfaceImproveParams& p = {});

/// Radius ratio 2 r_in / r_circ of a triangle (1 equilateral, 0 degenerate).
double triangle_radius_ratio(const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace pm
