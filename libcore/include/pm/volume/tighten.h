#pragma once
// Tightening of a binary mask (Williams & Rossignac 2005; dissertation §2.5.2,
// §6.6.1; SPEC §2): with a ball of radius r,
//   round  = opening(S, r)   (union of the balls of radius r inside S),
//   fillet = closing(S, r)   (complement of the opening of the complement),
//   mortar = fillet \ round.
// The tightened surface stays inside the mortar and has radius of curvature
// >= r in practice. It is computed as a level-set mean-curvature flow of the
// signed distance of S, clamped after every step between the signed
// distances of the fillet and the round, re-distanced periodically, until
// the zero set stops moving. S is the mask's voxels as a solid whose surface
// lies halfway between inside and outside nodes (the level 0.5 of the mask's
// trilinear interpolation); round and fillet are Euclidean (by distance
// transforms: round = {x : dist(x, {d_S <= -r}) <= r}, and dually).
//
// Sign convention: the output is a signed distance volume, world units,
// NEGATIVE inside (like every distance field here and F < iso for particles).
// Chapter 6's indicator functions want positive = material: set
// `positive_inside` to negate the output.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "pm/base/volume.h"

namespace pm {

struct TightenParams {
  double radius = 1;  ///< r, world units (> 0)
  /// K >= 1: resample the mask to K times the resolution first (trilinear
  /// interpolation of the 0/1 mask, level 0.5), for r below a voxel or so.
  /// The output grid has spacing h/K and (n-1)K+1 nodes per axis.
  int upsample = 1;
  /// Flow steps; 0 = automatic: until converged, at most 20 (r/h)² + 160.
  int max_iterations = 0;
  /// Converged when no node next to the zero set moves more than
  /// tolerance · h in a step, or when those nodes moved less than
  /// kTightenCycleShare · tolerance · h in the mean over a whole
  /// re-distancing cycle (voxels;
  /// a few nodes on thin necks or at clamped saddles never settle while
  /// the zero set as a whole converges geometrically).
  double tolerance = 1e-3;
  /// Check the flowing field every N steps (>= 1) and re-distance it when
  /// |grad phi| at the zero set is off 1 by more than 0.5 while the zero set
  /// still moves more than 10 · tolerance a step (later it only perturbs it).
  int reinit_every = 25;
  bool positive_inside = false;  ///< negate the output (Chapter 6 indicators)
  bool keep_mortar = false;      ///< also return the round and fillet distances
  /// Outside voxels added on every side before tightening: -1 = as many as
  /// the closing needs (r + 3 voxels beyond the mask), >= 0 = exactly this
  /// many (a mask touching the border is then cut off there; tighten_labels
  /// pads the label map itself instead).
  int pad = -1;
  /// > 0: outside the material the output distance is accurate only within
  /// this distance of the surface (world units) and within about a voxel
  /// farther out (the inside stays accurate everywhere); applied only when
  /// the outside reaches the grid's faces, so that a bounded outside (e.g.
  /// the background's, which is the union of the other materials) keeps its
  /// exact depth. 0 = accurate everywhere.
  double outside_band = 0;
};

/// `tighten --outside-band auto`, in voxel diagonals of the output grid:
/// medialaxis --side inside reads the outside up to 3.5 diagonals from the
/// surface, and the band's accurate values reach a little less far than the
/// band where the closest-disc propagation would have come through nodes
/// beyond it (at 4 diagonals a few frog nodes within 3.5 changed, by < 0.08
/// mm; at 6 none).
constexpr double kTightenOutsideBandDiagonals = 6.0;
/// That band in world units for an input grid `g` resampled `upsample` times.
double tighten_outside_band_auto(const Geometry& g, int upsample);

struct TightenResult {
  /// float32 signed distance to the tightened surface, world units, negative
  /// inside (positive with positive_inside). Its grid is the input's, padded
  /// (see `pad`) and upsampled; the geometry says where it lies.
  Volume distance;
  /// With keep_mortar: signed distances of the round and the fillet on the
  /// same grid, negative inside whatever positive_inside says; the mortar is
  /// {round >= 0 and fillet <= 0}. Accurate within a few voxels of the
  /// mortar; FLT_MAX far outside the mask's bounding box.
  Volume round, fillet;
  std::size_t pad = 0;          ///< voxels of the input grid added on every side (0 = none)
  int iterations = 0;           ///< flow steps taken
  int reinits = 0;              ///< re-distancings of the flowing field
  bool converged = false;
  double last_change = 0;       ///< largest move of the last step, voxels
  double cycle_change = 0;      ///< mean move of the zero set over the last whole cycle, voxels (0 = none)
  std::size_t mortar_nodes = 0; ///< nodes where the round and fillet differ (the flow runs there)
  std::size_t inside_voxels = 0;  ///< inside voxels of the input mask
  /// The radius asked for, and the one used (world units). They differ where
  /// the asked radius would erase the mask (thinner than 2r everywhere: the
  /// round is empty and the flow shrinks it to a dot): the radius is halved
  /// until it is at most kTightenRoundDepth of the mask's depth, and is 0
  /// (the mask's own surface, untightened) below kTightenMinRadiusVoxels fine voxels.
  double requested_radius = 0, radius = 0;
};
/// Why r.radius is smaller than r.requested_radius, for a warning: "tightening
/// at radius 1.5 would erase it (...); tightened at radius 0.375 instead".
std::string tighten_radius_note(const TightenResult& r);
/// Smallest radius tried for a mask that a larger one would erase, in fine voxels.
constexpr double kTightenMinRadiusVoxels = 0.25;
/// The radius used is at most this share of the mask's depth (its deepest
/// inside point's distance to its surface), so the round is a solid, not a dot.
constexpr double kTightenRoundDepth = 0.9;
/// Converged, too, when the zero set's mean move over a whole re-distancing
/// cycle is below this share of the tolerance. A few nodes on thin necks
/// keep moving while the zero set as a whole settles geometrically (frog5's
/// background: 0.16, 0.025, 0.005, 0.0019, 0.0010, 0.0005 voxel per cycle of
/// 25 steps), so the largest move alone ran every such label to the step cap.
/// At a share of 1 frog15's worst interface triangle fell from 0.457 to 0.291
/// (ch6 results; it sits in a thin void between three materials, where any
/// change of the surfaces moves it); at 0.5 it is 0.502.
constexpr double kTightenCycleShare = 0.5;

/// Defaults taken from the volume's header and size (`tighten --radius auto
/// --upsample auto`):
///  * upsample: 1 when every axis has at least kTightenMinVoxels voxels; else the
///    smallest K with K * (smallest axis) >= 2 * kTightenMinVoxels, at most 8 (a 2x2x2
///    label map gets 8), so that tiny volumes have room for a smooth surface;
///  * radius: the largest voxel spacing (world units), so slice terraces of
///    anisotropic scans are smoothed away; divided by the automatic upsampling
///    factor when that is > 1 (the voxels of a tiny volume are its features).
/// A downsampled input (morph --downsample) has the larger spacing already.
struct TightenDefaults {
  double radius = 0;  ///< world units
  int upsample = 1;
};
constexpr std::size_t kTightenMinVoxels = 8;
/// `radius` <= 0 and `upsample` <= 0 mean auto; given values are returned as they are.
TightenDefaults tighten_defaults(const Volume& v, double radius, int upsample);

/// Inside flags (1/0) of a binary mask: exactly two distinct voxel values, the
/// larger one is inside. \throw InputError naming `what` for one value
/// ("empty mask") or more than two ("expected a binary mask (2 distinct
/// values), got 187 values").
std::vector<std::uint8_t> binary_mask_inside(const Volume& mask, const std::string& what = "mask");

/// Tighten a binary mask. If the mask comes within r + 3 voxels of the volume
/// border, the grid is padded with outside voxels (result.pad > 0; the
/// geometry's origin moves accordingly) so the closing is not clipped.
/// \throw UsageError for radius <= 0, upsample < 1 or > 8, reinit_every < 1;
/// InputError for a mask that is not binary, an empty mask, non-orthogonal
/// axes, or a grid that would exceed 2^31 nodes.
TightenResult tighten(const Volume& mask, const TightenParams& p);

/// Chapter 6 per-material tightening of a label map: every label present
/// (label 0 included) is tightened as its own mask with radius p.radius, on
/// the label map's grid upsampled p.upsample times (spacing h/K, (n-1)K+1
/// nodes per axis, same origin), so all outputs share one grid. To keep the
/// volume border from acting as an interface, the label map is first padded
/// by r + 3 voxels replicating its border labels, and the results are cropped
/// back. `sink(label, result)` receives each label's result in increasing
/// label order (result.pad is 0; result.distance is negative inside unless
/// p.positive_inside). \throw InputError for a label map with non-integer
/// values or fewer than 2 labels; as tighten() otherwise.
void tighten_labels(const Volume& labels, const TightenParams& p,
                    const std::function<void(int label, TightenResult&& result)>& sink);

namespace detail {
/// One step of tighten's clamped mean-curvature flow, exposed for the test
/// that holds its AVX2 copy to the baseline one bit for bit. `active`: the
/// flowing nodes (ascending indices into the box, none on its border); cur
/// and next: the box's values (next is written at the active nodes); lo, hi:
/// the clamp per active node; h: spacings; returns the largest move of a
/// node next to the zero set within `near` of it. avx2 selects the AVX2 copy
/// (ignored where the CPU or the build has none).
double tighten_flow_step(const std::vector<std::uint32_t>& active, const Dims& box, const std::vector<float>& cur,
                         std::vector<float>& next, const std::vector<float>& lo, const std::vector<float>& hi,
                         const double h[3], double dt, double near, bool avx2);
}  // namespace detail

}  // namespace pm
