#pragma once
// Particle seeds from marching-cubes vertices (SPEC §5, dissertation §5.3.3):
// one seed per grid edge crossing the isosurface, so that every component of
// the surface is seeded; and, for label maps, seeds on every material
// boundary, triple line and quadruple point (Chapter 6).
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>

#include "pm/base/volume.h"
#include "pm/field/volume_field.h"
#include "pm/io/mesh.h"

namespace pm {

struct McInitParams {
  double iso = 0;  ///< isovalue c, in voxel value units (surface F = c, F < c inside)
  /// Reconstruction of F (SPEC §1): B-spline by default, Catmull-Rom, or the Chapter-5 mix.
  VolumeFieldParams field;
  /// Keep about one seed per decimate^3 grid cells (per surface component); 1 keeps all.
  int decimate = 1;
  /// Most Newton steps projecting a seed onto F = c along grad F; a seed stops
  /// once on the surface (0: raw marching-cubes vertices). With the mix the
  /// gradient is the B-spline's, not the value kernel's, so convergence is
  /// only linear: 20 steps reach 1e-6 where 6 do not.
  int project_steps = 20;
};

struct McInitResult {
  /// Seeds: vertices (world units), unit normals = grad F / |grad F| (pointing
  /// to increasing F: outwards), vertex scalar "component" (0-based id).
  Mesh seeds;
  std::size_t crossings = 0;    ///< grid edges crossing the isosurface (seeds before decimation)
  std::size_t components = 0;   ///< connected components of crossing cells
  /// Seeds within the tolerance of F = c after projection (the others keep
  /// their edge position; with project_steps = 0: 0).
  std::size_t projected = 0;
  double max_residual = 0;      ///< largest |F(seed) - c| after projection
};

/// Marching-cubes seeds of the isosurface F = iso of the reconstructed field.
/// 1. The reconstructed field is resampled at the grid nodes (F at the nodes
///    is the separable kernel filter of the voxels: B-spline = (1,4,1)/6 per
///    axis; Catmull-Rom and the mix interpolate, so the voxels themselves),
///    so the crossings are those of the surface the particles will sample.
/// 2. One seed per grid edge whose resampled endpoint values lie on both
///    sides of iso (one < iso <= the other), at the linear interpolation.
/// 3. Each seed takes up to project_steps Newton steps
///    x <- x - (F(x) - c) grad F / |grad F|^2; the projection is kept if it
///    converges to |F - c| <= 1e-6 (|c| + value range) within one voxel
///    diagonal of the edge point.
/// 4. Components: crossing cells (2x2x2 node blocks with both signs) joined
///    through shared faces that have a sign change.
/// 5. Decimation keeps, per component and per block of decimate^3 cells, the
///    seed nearest the block centre.
/// \throw InputError: iso outside [min, max] of the voxels ("no surface: the
/// isovalue 5 is outside the value range [0, 1]"), no crossing edge, NaN/Inf
/// voxels, fewer than 2 nodes along an axis. UsageError: decimate < 1.
McInitResult mc_seeds(const Volume& v, const McInitParams& p);

struct JunctionParams {
  int decimate = 1;  ///< keep about one seed per decimate^3 cells, per label set
};

struct JunctionResult {
  /// Seeds (world units) with vertex scalars "junction" (2, 3 or 4) and
  /// "label_a" < "label_b" < "label_c" < "label_d" (-1 where unused).
  /// Normals: for pair seeds the unit world direction of the grid edge from
  /// label_a's voxel to label_b's; zero for triple and quadruple seeds.
  Mesh seeds;
  std::map<std::pair<std::int64_t, std::int64_t>, std::size_t> pairs;  ///< seeds per touching pair
  std::size_t triples = 0, quadruples = 0;                             ///< triple / quadruple seeds
};

/// Seeds on the material boundaries of a label map (voxels are node samples):
///  * pairs: the midpoint of every grid edge whose two nodes have different
///    labels i < j (label_a = i, label_b = j, junction = 2);
///  * triples: the centre of every cell (2x2x2 node block) whose 8 nodes hold
///    exactly 3 distinct labels (label_a..c, junction = 3): the triple lines;
///  * quadruples: the centre of every cell with 4 or more distinct labels
///    (the 4 smallest as label_a..d, junction = 4).
/// Every label takes part, background 0 included.
/// \throw InputError for non-integer values, negative labels, fewer than 2
/// labels. UsageError: decimate < 1.
JunctionResult junction_seeds(const Volume& labels, const JunctionParams& p = {});

}  // namespace pm
