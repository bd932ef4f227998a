#pragma once
// Dynamic particle system sampling an implicit surface F = iso (SPEC §3,
// Meyer 2008 Chapter 3): particles constrained to the surface repel each
// other with a compact energy until they settle in a near-hexagonal packing,
// uniform (spacing s), curvature-adaptive (density ρ) or following a sizing
// field h(x). Population control splits/deletes particles towards the ideal
// energy; coarse-to-fine and uniform bins make it fast.
//
// Scale convention: the pair vector is r_ij = α_ij (x_i - x_j) with σ = 1 and
//   α_ij = β (1 + ρ s C_ij / (2π)) / s      (curvature mode, C_ij mean curvedness)
//   α_ij = β / min(h(x_i), h(x_j))           (sizing mode)
// where β = 0.5/cos(π/6). The factor β puts the hexagonal 1-ring at |r| = β,
// so on a plane the distance between neighbours is s (or h): this is the
// scaling SPEC §3 asks for ("mean nearest-neighbour distance ≈ s"). The
// local spacing of particle i is s_i = β / α_ii; its interaction radius with
// j is 1/α_ij (≈ 1.73 s_i).
//
// Determinism: particles are processed Gauss-Seidel in bin order; bins are
// coloured into 8 classes (bx%2, by%2, bz%2) and only bins of one colour run
// in parallel (they are >= 2 bins apart, so none reads what another writes),
// so the result is bit-identical for any thread count. All randomness is a
// counter-based hash of (seed, particle id, iteration).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "pm/base/vec.h"
#include "pm/field/field.h"
#include "pm/field/sizing.h"
#include "pm/sample/engine.h"

namespace pm {

struct ParticleParams {
  double iso = 0;              ///< isovalue c; the surface is F = c
  double spacing = 0;          ///< s: planar particle spacing, world units (> 0; ignored with a sizing field)
  double density = 0;          ///< ρ: particles per radian on curved parts; 0 = uniform spacing
  double alpha_cap = 10;       ///< curvature mode: local spacing never drops below s / alpha_cap (>= 1)
  ParticleEnergy energy = ParticleEnergy::cotangent;
  double tolerance = 0.0015;   ///< converged when the system energy Σ E_i drops by less than this
                               ///< fraction in one sweep
  /// Coarse-to-fine: the tolerance of every level but the last (at least
  /// `tolerance`): a coarse level only has to be near its packing, since its
  /// particles are split into four and relaxed again. 5e-4 measured: brain
  /// mask 36k vertices 73 -> 64 updates per particle, 259k 64 -> 54, rr
  /// mean within 0.0002; SPEC's 0.15% saved more (48 at 259k) but left the
  /// skull a hole whose triangle fell to rr 0.12 (0.59 at 5e-4, 0.67 without).
  double coarse_tolerance = 0.0005;
  /// Coarse-to-fine: the population tolerance of every level but the last,
  /// at least population_tolerance. A converged coarse level kept trading a
  /// few dozen splits for as many deletions (0.15% of 16k particles on the
  /// brain mask) for 150 sweeps at 0.1%; at 1%: 255 -> 112 sweeps, 53 -> 45
  /// updates per particle at 259k, rr min 0.712 -> 0.725, mean 0.9739 both.
  double coarse_population_tolerance = 0.01;
  int max_iters = 2000;        ///< sweeps per level (coarse-to-fine runs several levels)
  int population_interval = 50;  ///< iterations between population checks while not converged
  bool population_control = true;  ///< split/delete particles towards the ideal energy
  /// The run ends when the energy has converged and at most this fraction of
  /// the particles wants to split or die (0 = none, SPEC's literal rule; with
  /// tens of thousands of particles on noisy data a few always do).
  double population_tolerance = 0.001;
  std::size_t count = 0;       ///< fixed particle count: scale the local spacing (s or h) instead of
                               ///< splitting/deleting (0 = off); `spacing` is then the starting value
  std::size_t init_count = 500;  ///< random initial points in the domain (when no seeds are given)
  /// Without seeds: start from the crossings of F = iso along the edges of a
  /// cubic lattice over the domain (step ≈ 1.15 × the starting spacing, which
  /// gives about the hexagonal count on a plane) instead of `init_count`
  /// random points; falls back to random points when no edge crosses. Seeds
  /// every component larger than the step and saves the many population
  /// doublings a few random points would need on a large surface.
  bool init_lattice = false;
  bool coarse_to_fine = false; ///< converge with every local spacing × 2^k, split each particle into 4, halve, repeat
  double coarse_start = 0;     ///< coarse-to-fine: largest spacing, world units (0 = 4 × field resolution);
                               ///< levels k = floor(log2(coarse_start / s)), with a sizing field s = median h
  std::uint64_t seed = 1;      ///< random seed
  bool progress = true;        ///< report through pm::Progress (stderr, tool-controlled)
  /// Settled-particle skipping (EngineParams::settled_move): fraction of the
  /// local spacing below which a particle whose neighbourhood also moved
  /// less counts as settled (0 = off).
  double settled_move = 0;
  /// Seeds closer than this fraction of the starting local spacing to a kept
  /// seed are dropped before relaxing (0 = keep all; every seed still
  /// anchors its component).
  double seed_thinning = 0;
  int reproject_steps = engine_constants::kReprojectSteps;  ///< (Gauss-)Newton steps after a tangent move (>= 1)
  /// Adaptive step: λ_i × this after a first-try acceptance, ÷ after a
  /// rejection (> 1; see EngineParams::step_factor); with the quadratic step
  /// control the bound of one change.
  double step_factor = engine_constants::kLambdaFactor;
  StepControl step_control = StepControl::quadratic;  ///< see StepControl
  /// Quad packing (SPEC §7, issue #20): two particle types, mixed at random
  /// (half each) at initialisation; like pairs repel √2 farther than unlike
  /// ones (pm::set_quad_types), so the packing settles towards a checkerboard
  /// on a square lattice whose unlike neighbours sit `spacing` apart.
  bool quads = false;
};

struct ParticleResult {
  std::vector<Vec3> positions;    ///< #N, world units, |F - iso| <= 1e-5
  std::vector<Vec3> normals;      ///< #N unit normals ∇F/|∇F| (outward for F < iso inside)
  std::vector<double> energy;     ///< #N particle energy E_i (σ = 1 units)
  std::vector<double> spacing;    ///< #N local spacing s_i = β/α_ii, world units
  std::vector<double> curvature;  ///< #N curvedness C = sqrt(κ1² + κ2²), 1/world units
  std::vector<int> types;         ///< #N particle type 0 or 1 with `quads`, else empty

  int iterations = 0;             ///< sweeps over all levels
  int levels = 1;                 ///< coarse-to-fine levels run (1 = single level)
  bool converged = false;         ///< the last level converged with a stable population
  std::size_t splits = 0, deletions = 0;
  std::size_t thinned = 0;         ///< seeds dropped by seed_thinning
  std::size_t dropped_init = 0;   ///< initial points / seeds whose projection failed
  /// Particles re-inserted on the final level at initial points left without
  /// a particle nearby (a component emptied on a coarse level; see below).
  std::size_t refilled = 0;
  double energy_final = 0;        ///< Σ E_i at the end
  double energy_ideal = 0;        ///< N · 6 E(β)
  double mean_neighbours = 0;     ///< mean number of particles within the interaction radius
  double final_spacing = 0;       ///< s at the end (differs from the input with `count`; with a sizing
                                  ///< field: the factor applied to h)
  std::uint64_t field_evaluations = 0;  ///< calls to F (value, gradient or Hessian)
  std::uint64_t particle_updates = 0;   ///< particle moves attempted (Σ particles over sweeps)
  std::uint64_t list_builds = 0;        ///< neighbour-list (and bin) rebuilds, <= iterations
  EngineStats engine;                   ///< the engine's counters (trials, rejections, failures, ...)
  /// Wall-clock seconds: initial projection; sweeps (with binning); population
  /// control, energy measurements and coarse-to-fine splits; final measurements.
  double seconds_init = 0, seconds_relax = 0, seconds_population = 0, seconds_finish = 0;
};

/// Distribute particles on F = iso.
///   field:  the implicit; must be C¹ (C² for density > 0) and safe to
///           evaluate from several threads at once.
///   seeds:  initial points (#S, world units); empty = `init_count` random
///           points in field.domain(). Every initial point is projected with up
///           to 20 Newton steps; failures are dropped and counted.
///   sizing: optional sizing field h (world units); replaces s and ρ.
/// Population control splits a particle when E_i (1+u)/2 < 0.35 E_ideal and
/// deletes it when E_i (1+u)/2 > 1.75 E_ideal (u uniform on [0,1]), so every
/// count whose particle energies lie in [0.7, 1.75] E_ideal is stable: the
/// final count lies between about 0.86 and 1.27 times the hexagonal estimate
/// area/((√3/2) s²), depending on how the population got there.
/// Every component the initial points reach keeps particles: the projected
/// initial points are kept as anchors, and on the final coarse-to-fine level an anchor with
/// no particle within 1.5 local spacings (normals on the same side) gets a
/// particle back, and population control never deletes the last such
/// particle of an anchor. (On coarse levels a component smaller than one
/// particle's share, or close to a larger one, may lose all its particles.)
/// Not converging within max_iters is not an error (result.converged).
/// \throw UsageError when spacing <= 0 or larger than the domain's diagonal
///   (without sizing), density < 0, alpha_cap < 1,
///   tolerance <= 0, population_tolerance < 0, max_iters < 1,
///   population_interval < 1, or init_count = 0 without seeds;
///   InputError when a seed is not finite, no initial point reaches the
///   surface, a projected particle lies outside the sizing field's box, or
///   `count` particles cannot be placed.
ParticleResult distribute_particles(const ScalarField& field, const std::vector<Vec3>& seeds,
                                    const SizingField* sizing, const ParticleParams& params);

}  // namespace pm
