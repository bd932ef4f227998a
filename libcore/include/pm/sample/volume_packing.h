#pragma once
// Sphere packing inside a region (SPEC §7 "Volume packing", issue #19): the
// particles of the one engine (pm/sample/engine.h) under the volume
// constraint F < iso (pm/sample/volume_constraint.h), with the boundary's
// particles (the vertices of the final surface or interface mesh) held
// fixed so that they repel the free interior ones. The interior points and
// the boundary mesh then go to a conforming tetrahedralisation
// (pm/mesh/tet_conform.h).
//
// Spacing: the sizing field h(x) (world units) of the surface pipeline
// extended inward by gradient limiting (pm::interior_sizing in
// pm/volume/gradlimit.h), or a constant spacing. A free particle's ideal
// neighbours are the 12 of a close packing.
//
// Seeding: an octree over the region's box, whose leaves (cubes of edge up
// to 2 h(centre)) hold a cubic lattice at the density of a close packing at
// distance h, kept inside F < iso; points closer than `seed_clearance` × h
// to a boundary particle or to an earlier seed are dropped (thin_points).
// Population control then splits and deletes towards the ideal density.
#include <array>
#include <cstdint>
#include <vector>

#include "pm/base/vec.h"
#include "pm/field/field.h"
#include "pm/field/materials.h"
#include "pm/field/sizing.h"
#include "pm/sample/engine.h"

namespace pm {

struct VolumePackParams {
  /// Sizing field (world units); null = the constant `spacing`.
  const SizingField* sizing = nullptr;
  double spacing = 0;          ///< world units, used when sizing is null (> 0)
  double seed_clearance = 0.7; ///< seeds keep this many h from boundary particles and each other
  ParticleEnergy energy = ParticleEnergy::cotangent;
  double tolerance = 1e-3;     ///< converged when the system energy drops by less than this fraction
  int max_iters = 400;         ///< iteration limit (not converging is a warning)
  int population_interval = 25;
  double population_tolerance = 0.002;
  bool population_control = true;
  std::uint64_t seed = 1;
  bool progress = true;
};

struct VolumePackResult {
  std::vector<Vec3> points;      ///< free interior particles, world units
  std::vector<double> spacing;   ///< their local spacing h, world units
  std::vector<int> labels;       ///< their material label (one material: 1)
  std::size_t fixed = 0;         ///< boundary particles held fixed
  std::size_t seeds = 0;         ///< seeds placed before relaxation
  bool converged = true;         ///< every region's relaxation converged
  int iterations = 0;            ///< summed over regions
  std::size_t splits = 0, deletions = 0;
  EngineStats stats;             ///< summed over regions
};

/// Pack the inside F < iso of one region whose boundary particles are
/// `fixed` (world units; e.g. the surface mesh's vertices). Every returned
/// point satisfies F < iso. Deterministic for a fixed seed and any thread
/// count. `label` is stored in result.labels.
/// \throw UsageError for spacing <= 0 without a sizing field or other
/// invalid params. A region no seed fits in (thinner than its spacing) gets
/// no free particles, with a warning.
VolumePackResult pack_volume(const ScalarField& field, double iso, const std::vector<Vec3>& fixed,
                             const VolumePackParams& p, int label = 1);

/// Pack every material of `materials` except `outside_label`: material m is
/// the region where its indicator is the largest (pm::material_region_field),
/// and its fixed particles are the vertices of the triangles with m on one
/// side (`triangle_labels[i]` = (a, b) of triangle i). Results of the
/// materials are concatenated in the order of materials.labels.
VolumePackResult pack_materials(const MaterialSet& materials, int outside_label, const std::vector<Vec3>& vertices,
                                const std::vector<std::array<int, 3>>& triangles,
                                const std::vector<std::array<int, 2>>& triangle_labels, const VolumePackParams& p);

}  // namespace pm
