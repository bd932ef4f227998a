#pragma once
// Gradient limiting of a sizing field (Persson 2006; SPEC §5, dissertation
// §5.3.2): the largest field h <= h0 with |grad h| <= delta, where h0 is the
// input sizing field (world units: spacing and direction matrix come from the
// volume's header, so anisotropic voxels are honoured).
//
// Known and unknown voxels: a voxel whose h0 is <= 0 (or not finite, when
// allowed) is "unknown", e.g. outside the band around the surface where a
// sizing field was computed. Unknown voxels receive the limited extension
// min_y (h0(y) + delta |x - y|) over the known voxels y, so the output is
// finite and > 0 everywhere and can size interior volume packing later
// (Chapter 7). Known voxels never increase: h <= h0 wherever h0 was known.
#include <limits>
#include <cstddef>
#include <vector>

#include "pm/base/volume.h"

namespace pm {

enum class GradLimitMethod {
  /// Ordered propagation of "sources" over the 26-neighbour lattice (about
  /// increasing h, label-correcting): every voxel gets h(x) = h0(s) + delta
  /// |x - s| for the best source s offered by a neighbour, or h0(x) if
  /// smaller. This approximates the exact envelope min_y (h0(y) + delta
  /// |x - y|) from above (a voxel can miss its best source where sources
  /// compete; measured: a few % of delta times a voxel), and it satisfies the
  /// discrete bound exactly up to float rounding (about 1e-7 h):
  /// |h(x) - h(y)| <= delta |x - y| for every pair of 26-neighbours. One pass;
  /// h is held as float during the pass.
  propagate,
  /// Persson's explicit upwind iteration h <- h + dt (min(G, delta) - G) with
  /// G = sqrt(sum_axes max(D-h, 0)^2 + min(D+h, 0)^2) and the stable step
  /// dt = 0.9 / sqrt(2 sum_a 1/s_a^2) (s_a: spacing), until the largest
  /// relative change is < tolerance. Slow (the number of sweeps grows with
  /// the grid's diameter); a reference for small volumes. Its fixed point
  /// satisfies G <= delta, which at ridges (both neighbours of an axis
  /// lower) is stricter than the 26-neighbour bound.
  upwind,
};

struct GradLimitParams {
  double delta = 0.3;        ///< bound on |grad h|, dimensionless (world units per world unit)
  double tolerance = 1e-5;   ///< upwind: stop when max |h_new - h| / h < tolerance
  GradLimitMethod method = GradLimitMethod::propagate;
  std::size_t max_iterations = 100000;  ///< upwind: give up (InputError) after this many sweeps
  bool nonfinite_unknown = false;       ///< treat NaN/Inf voxels as unknown instead of refusing them
  /// Values above this are not wanted: the output is min(h, ceiling), and
  /// propagate stops growing values there (on a fine grid around a surface,
  /// most voxels lie beyond it; +inf = no ceiling). A voxel just below the
  /// ceiling whose best path ran through a neighbour above it may come out a
  /// little higher, still within the gradient bound (brain mask interior
  /// sizing: 1 of 16.7M voxels, by 3e-4 relative; 7.5 s -> 2 s).
  double ceiling = std::numeric_limits<double>::infinity();
  /// Cap the result (and `ceiling`) at c = K + δ times two voxel diagonals,
  /// K the largest value the known voxels get when limiting runs among the
  /// known voxels alone (an upper bound of their final values: fewer paths;
  /// at most the largest known value). Every voxel whose limited value lies
  /// below c, every known voxel among them, gets the value it gets without a
  /// cap, and the far field stays flat instead of growing by δ per unit of
  /// distance, which saves filling the whole grid (a band around a surface
  /// is a few percent of it; frog, 5 materials: K = 9.0 where the largest
  /// known value is 73.4, and 1.4M of 4.3M voxels lie below c). min(h, c) of
  /// a δ-Lipschitz h is δ-Lipschitz.
  bool flat_far_field = false;
};

struct GradLimitResult {
  Volume h;                  ///< float32 (double if the input was double), input dims and geometry
  std::size_t known = 0;     ///< voxels with a usable input value
  std::size_t unknown = 0;   ///< voxels filled by the extension
  std::size_t lowered = 0;   ///< known voxels whose value decreased
  std::size_t iterations = 0;  ///< upwind sweeps (propagate: 1)
  /// Largest face-neighbour slope |h(x) - h(y)| / |x - y| of the output
  /// divided by delta (propagate: 1 up to float rounding, about
  /// 1e-7 h / (delta * spacing)).
  double max_slope_ratio = 0;
  /// The cap applied: interior_sizing's max_size (or the largest kept h);
  /// gradient_limit's with flat_far_field (else `ceiling`, +inf = none).
  double cap = 0;
};

/// \throw UsageError for delta <= 0 or tolerance <= 0; InputError for an
/// integer voxel type (a label map, not a sizing field), NaN/Inf voxels
/// (unless nonfinite_unknown), or no known voxel at all; InputError when
/// upwind does not converge within max_iterations.
GradLimitResult gradient_limit(const Volume& h0, const GradLimitParams& p = {});

/// Sizing inside a volume for volume packing (Chapter 7, issue #19): the
/// surface pipeline's h is kept on the voxels within `band` (world units) of
/// a boundary point (the final surface's vertices) and is unknown
/// everywhere else; gradient limiting with `delta` then grows it away from
/// the surface, h(x) = min_y (h(y) + delta |x - y|) over the kept voxels y,
/// and `max_size` (world units) caps it; max_size = 0 caps it at the
/// largest kept h, the surface's coarsest spacing. (The particle engine's
/// bins are as wide as the largest interaction radius, so an interior far
/// coarser than the surface makes every bin near the surface crowded:
/// raising the cap coarsens the deep interior at a cost in speed.)
/// \throw UsageError for band <= 0, delta <= 0 or max_size < 0; InputError
/// when no boundary point lies within band of a voxel of h.
GradLimitResult interior_sizing(const Volume& h, const std::vector<Vec3>& boundary, double band, double delta,
                                double max_size);

}  // namespace pm
