#pragma once
// Initial sizing field of dissertation §5.3.2 and §6.6.2 (SPEC §5, §6):
//   h0(x) = 2ε · min(λ(x), 1/|κmax(x)|) / g,  then h = max(h0, hmin),
// where λ is the local feature size (distance to the nearest medial-axis
// point), κmax the principal curvature of larger magnitude of the
// reconstructed distance field (value Catmull-Rom, derivatives cubic
// B-spline), and g = 1.5 the distance contraction (Euclidean distances
// between neighbouring particles on a curved surface; on by default).
//
// Where: only nodes within `band` voxels of the surface (|d| <= band times
// the smallest spacing) get a value; every other node is 0 = unknown, the
// convention of gradlimit, which extends the field over them.
// Both λ and κmax are evaluated at the node's foot point (its closest
// surface point, p = x - d ∇d/|∇d| refined once) rather than at the node, so
// that a value interpolated on the surface is the surface's own LFS and
// curvature (at the node itself, a sphere's outside nodes would see R + d).
//
// Several surfaces (Chapter 6: one distance volume and medial axis per
// material) give the minimum over the surfaces that know a node.
#include <cstddef>
#include <string>
#include <vector>

#include "pm/base/volume.h"

namespace pm {

struct SizingFieldParams {
  double eps = 0.5;          ///< ε (> 0), dimensionless; C = 2ε
  double hmin = 0;           ///< lower bound on h, world units (>= 0; Chapter 6: the tightening radius)
  double band = 4;           ///< half-width of the band of known nodes, voxels (> 0)
  bool contract = true;      ///< divide by the contraction g
  double contraction = 1.5;  ///< g (>= 1)
  bool at_foot_point = true; ///< evaluate λ and κ at the foot point (false: at the node, as printed in §5.3.2)
};

/// One surface: its signed distance volume (negative inside, world units)
/// and its medial-axis points (world units, e.g. from medial_axis()).
struct SizingSurface {
  const Volume& sdf;
  const std::vector<Vec3>& medial_axis;
  std::string name = {};  ///< its file, named in errors after "surface N" (empty: none)
};

struct SizingFieldResult {
  Volume h;    ///< float32 sizing field, world units; 0 = unknown (outside the band)
  Volume lfs;  ///< float32 λ (minimum over the surfaces), world units; 0 outside the band
  std::size_t known = 0;              ///< nodes with h > 0
  std::size_t curvature_limited = 0;  ///< known nodes where 1/|κmax| < λ decided h
  std::size_t hmin_limited = 0;       ///< known nodes raised to hmin
  double h_lo = 0, h_hi = 0;          ///< range of the known h
  double lfs_lo = 0, lfs_hi = 0;      ///< range of the known λ
};

/// Sizing field on the grid of the first surface's volume.
/// \throw UsageError for eps <= 0, hmin < 0, band <= 0, contraction < 1, or
/// no surfaces; InputError when a volume is not a signed distance volume (see
/// require_distance_volume), a medial axis has no points, or the volumes'
/// grids differ (dims, origin or directions).
SizingFieldResult sizing_field(const std::vector<SizingSurface>& surfaces, const SizingFieldParams& p = {});

}  // namespace pm
