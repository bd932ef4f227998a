#pragma once
// Corner-angle smoothing of a quad-dominant surface mesh that samples an
// implicit surface F = iso (issue #20): a converged two-type packing is a
// square lattice whose shear is soft, so its quads are often parallelograms
// and trapezoids with corners 20-40° off 90°. Each vertex in turn moves in its
// tangent plane down the gradient of
//   Σ over the corners of its faces ((θ − θ*) / 90°)² + λ Σ over its edges (ℓ / ℓ̄ − 1)²
// (θ* = 90° for quads, 60° for triangles; ℓ̄ the mean length of its edges
// before the move; the length term keeps quads from turning into long
// rectangles), is projected back onto F = iso with Newton, and keeps the move
// only when the objective drops, no face folds and no quad's scaled Jacobian
// falls below min(its value before, min_jacobian). Faces and topology are
// kept; Gauss-Seidel in vertex order, deterministic. Where the smoothed mesh
// crosses itself (thin parts; CGAL's test on the fan triangles), the vertices
// of the faces involved are frozen and the smoothing is redone from the
// start. World units.
#include <cstddef>

#include "pm/base/mesh.h"
#include "pm/field/field.h"

namespace pm {

struct QuadSmoothParams {
  int passes = 10;             ///< sweeps over the vertices (0 = nothing)
  double step = 0.2;           ///< first trial step, fraction of the vertex's mean edge length
  int halvings = 3;            ///< the step is halved at most this often per vertex and pass
  double length_weight = 0.1;  ///< λ above
  double min_jacobian = 0.3;   ///< floor of a quad's scaled Jacobian after a move (or its value before, if lower)
  double max_fold_deg = 30;    ///< a move may turn a face's normal by at most this much
  int newton_steps = 6;        ///< projection onto F = iso after a move
  double tolerance = 1e-6;     ///< |F − iso| / |∇F| accepted after projection, relative to the mean edge length
  int max_redos = 4;           ///< smoothings redone with more vertices frozen after crossings
};

struct QuadSmoothStats {
  std::size_t moves = 0;            ///< vertex moves kept (over all passes)
  std::size_t rejected = 0;         ///< trial moves refused (projection, fold, Jacobian) or not better
  double objective_before = 0, objective_after = 0;  ///< the corner term summed over all corners
  std::size_t frozen = 0;            ///< vertices frozen because moving them made faces cross
  int redos = 0;                     ///< smoothings redone
  int self_intersections = 0;        ///< intersecting pairs of fan triangles left (-1: not tested)
};

/// Smooth `m` in place. A vertex on an open or non-manifold edge stays.
/// \throw InputError when m fails validate().
QuadSmoothStats smooth_quads(PolyMesh& m, const ScalarField& field, double iso, const QuadSmoothParams& p = {});

}  // namespace pm
