#pragma once
// Medial axis (MA) points of a surface given by its signed distance volume,
// by the foot-point method of dissertation §5.3.1 (SPEC §5).
// Foot points (closest surface points) of all grid nodes first: where the
// grid gradients of a node and its six neighbours agree, p = q - d(q) g/|g|
// (g: central differences); elsewhere (near the MA, near the surface, at
// high curvature) p is found on the reconstructed field (value Catmull-Rom,
// derivatives cubic B-spline) by Newton steps for "q - p normal to the
// surface at p", started from the node's smoothed gradient and from its
// neighbours' grid gradients, keeping the closest foot point; nodes where
// that fails take the closest of their neighbours' feet.
// Then the test at node q: step along its characteristic u = (q - p)/|q - p|
// to the far face of q's voxel (the box of half-spacings around q), q'. The
// foot point p' of q' is the closest of the feet of the corners of q''s cell,
// and its characteristic u' the surface normal there. If u·u' < cos alpha,
// the segment q q' crosses the MA, where the tangent planes at p and p' are
// equidistant (first order); that point and its distance to the surface are
// kept. Both the inner MA (d < 0) and the outer MA (d > 0) are found.
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "pm/base/volume.h"
#include "pm/io/mesh.h"

namespace pm {

struct MedialAxisParams {
  double cos_alpha = 0.9;  ///< cos of the smallest turn of the characteristic that marks the MA, in (-1, 1)
  int foot_iterations = 3; ///< most Newton refinements of each foot point (>= 0)
  bool inside = true;      ///< find the inner MA (where d < 0)
  bool outside = true;     ///< find the outer MA (where d > 0)
  /// Only MA points of nodes with |d| <= max_distance (world units) are
  /// tested; infinity = all. The points kept are exactly those of the full
  /// run whose node lies within that distance (foot points are found on a
  /// wider shell so the kept nodes see the same neighbours).
  double max_distance = HUGE_VAL;
};

struct MedialAxisResult {
  /// MA points, world units, in slice-major grid order (deterministic), with
  /// vertex scalar "distance": distance to the surface, world units (>= 0).
  Mesh points;
  std::size_t nodes_refined = 0;  ///< nodes whose foot point needed the reconstructed field
  std::size_t inner = 0, outer = 0;  ///< points on the inner / outer MA
};

/// Check that `v` looks like a signed distance volume: a float type and more
/// than two distinct values, with a zero crossing (values of both signs).
/// \throw InputError naming `what`: "expected a signed distance volume
/// (float), got a uint8 mask", "... got a float volume with only 2 values",
/// "no zero crossing (values from 0.5 to 12)".
void require_distance_volume(const Volume& v, const std::string& what);

/// MA points of the zero level set of a signed distance volume (negative
/// inside, world units; any orthogonal-axes geometry). Nodes where the
/// reconstructed gradient is shorter than 0.5 (not a distance field, e.g.
/// clamped beyond a narrow band) are skipped.
/// \throw UsageError for cos_alpha outside (-1, 1), foot_iterations < 0 or
/// max_distance <= 0;
/// InputError as require_distance_volume.
MedialAxisResult medial_axis(const Volume& sdf, const MedialAxisParams& p = {});

/// The largest distance to the surface at which an MA point can still be the
/// nearest MA point of some surface point, so that the local feature size
/// (distance from a surface point to the nearest MA point) does not depend
/// on MA points farther out: every surface point p has a maximal ball on each
/// side whose centre is an MA point, so LFS(p) <= the ball's radius <= the
/// deepest |d| of that side, while an MA point m is at least d(m) from every
/// surface point. Only a side that does not reach the grid's faces counts
/// (its balls lie within the grid). The bound is twice the smaller of the
/// counting sides' depths (twice: sizingfield's foot-point estimate can lie
/// off the surface, see kLfsBoundDepths) plus two voxel diagonals for the
/// sampling of the MA; infinity when both sides reach the faces. World units.
double medial_axis_lfs_bound(const Volume& sdf);

/// uint8 volume on the grid of `like` with 1 at the node nearest to each
/// point inside the grid, 0 elsewhere.
Volume mark_points(const Volume& like, const std::vector<Vec3>& points);

}  // namespace pm
