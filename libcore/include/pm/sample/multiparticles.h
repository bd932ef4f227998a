#pragma once
// Hierarchical particle sampling of the junctions of a multi-material
// volume (SPEC §6, Meyer 2008 Chapter 6): one particle on every quadruple
// point (0-cell), then particle chains along every triple curve (1-cells),
// then particles on every interface surface between two materials
// (2-cells). Each level is relaxed with the particle energy of SPEC §3
// (pm/sample/particles.h) while the lower levels stay fixed and repel it: a
// particle sees the particles of its own cell and the fixed particles of
// every cell that bounds it (whose materials include its own).
//
// Scale: like pm::distribute_particles, r_ij = α_ij (x_i - x_j), σ = 1,
// α_ij = β / min(h_i, h_j) with β = 0.5/cos(π/6) and h the local spacing
// (uniform s, or a sizing field). Ideal energy n E(β) with n = 2 on curves
// (a chain at spacing h) and 6 on surfaces; population control splits a
// particle when its biased energy E_i (1+u)/2 is below 0.25 (curves) / 0.35
// (surfaces) of it and deletes it above 2.5 / 1.75.
//
// Constraint: a particle of cell {a, b, ...} stays on f_a = f_b = ... with
// no other material above (pm::project_to_cell, Gauss-Newton); a move that
// would leave the cell (cross a bounding curve, leave the domain) is
// rejected. Motion is projected onto the cell's tangent space (the plane
// normal to ∇(f_b - f_a) on surfaces, the tangent ∇(f_a - f_b) × ∇(f_b - f_c)
// on curves).
//
// Determinism: Gauss-Seidel in bin order with bins coloured (bx%2, by%2,
// bz%2) as in particles.cpp, and counter-based randomness: the result is
// bit-identical for a fixed seed and any thread count.
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "pm/base/vec.h"
#include "pm/base/volume.h"
#include "pm/field/junctions.h"
#include "pm/field/materials.h"
#include "pm/field/sizing.h"
#include "pm/io/mesh.h"
#include "pm/sample/particles.h"

namespace pm {

/// A seed point of a junction: 2, 3 or 4 material LABELS (label values, not
/// indices), ascending, -1 unused.
struct JunctionSeed {
  Vec3 x;
  std::array<int, 4> labels{{-1, -1, -1, -1}};
  int count = 0;  ///< 2, 3 or 4
};

/// Seeds from a point set as written by `mcinit --junctions` /
/// pm::junction_seeds: vertex scalars "junction" (2, 3, 4) and "label_a" ..
/// "label_d" (-1 unused).
/// \throw InputError (naming `what`) when the scalars are missing, a
/// junction value is not 2, 3 or 4, its labels are not distinct integers, or
/// a point is not finite.
std::vector<JunctionSeed> junction_seeds_from_mesh(const Mesh& m, const std::string& what = "seeds");

/// Seeds computed from the materials themselves: the argmax label of the
/// set sampled on a grid over its domain with the given spacing (world
/// units; 0 = the set's resolution), then pm::junction_seeds.
/// \throw InputError when the grid would exceed 512^3 nodes or only one
/// material occurs on it.
std::vector<JunctionSeed> junction_seeds_from_materials(const MaterialSet& m, double spacing = 0);

struct MultiParticleParams {
  double spacing = 0;          ///< s: uniform spacing, world units (used when no sizing field is given)
  ParticleEnergy energy = ParticleEnergy::cotangent;
  double tolerance = 0.0015;   ///< a level has converged when Σ E_i drops by less than this fraction in a sweep
  int max_iters = 1000;        ///< sweeps per level (curves, surfaces)
  int population_interval = 50;  ///< sweeps between population checks while not converged
  double population_tolerance = 0.001;  ///< converged with at most this fraction wanting to split/die
  bool surfaces = true;        ///< sample the 2-cells (false: stop after the curves)
  /// After the surfaces: merge surface particles of two interfaces sharing a
  /// material that are closer than h/4 into one triple-junction particle, and
  /// two of one interface closer than h/4 into one at their middle.
  bool repair_junctions = true;
  /// Quadruple points of one label quad closer than this fraction of the
  /// local spacing are one point (cull radius).
  double cull_fraction = 0.5;
  /// Initial thinning of the seeds of curves: a seed closer than this
  /// fraction of the local spacing to a kept seed of its cell is dropped.
  double seed_thinning = 0.7;
  /// The same for the seeds of surfaces. From `mcinit --junctions
  /// --decimate 1` seeds (frog5: 69k for 50k particles) 0.8 keeps 35k, and
  /// splits fill in: 51 sweeps against 74 from --decimate 2 seeds thinned at
  /// 0.7 (14k); 0.7 keeps 43k, too crowded to settle fast (113 sweeps).
  double surface_seed_thinning = 0.8;
  int seed_project_steps = 20;  ///< Gauss-Newton steps projecting seeds (SPEC: 10 iterations; 20 is safer)
  double projection_tolerance = 0;  ///< largest |f_a - f_b| on a cell, world units (0 = 1e-6 × the fields' resolution)
  std::uint64_t seed = 1;
  bool progress = true;
  double settled_move = 0;  ///< settled-particle skipping, see ParticleParams::settled_move (0 = off)
  int reproject_steps = engine_constants::kReprojectSteps;  ///< (Gauss-)Newton steps after a tangent move (>= 1)
  double step_factor = engine_constants::kLambdaFactor;  ///< adaptive step factor (> 1), see EngineParams
  StepControl step_control = StepControl::factor;        ///< see StepControl
};

/// Per-level counts (level 0: quadruple points, 1: triple curves, 2: surfaces).
struct MultiLevelStats {
  std::size_t seeds = 0;          ///< seeds of this level given
  std::size_t seeds_unknown = 0;  ///< seeds naming a label that is not a material
  std::size_t seeds_failed = 0;   ///< seeds whose projection did not converge or was not dominant
  std::size_t seeds_culled = 0;   ///< duplicates / thinned seeds
  std::size_t cells = 0;          ///< distinct cells (label sets) with particles
  std::size_t particles = 0;      ///< final count
  int iterations = 0;
  bool converged = true;
  std::size_t splits = 0, deletions = 0;
  double energy_final = 0, energy_ideal = 0;
  double seconds = 0;
};

struct MultiParticleResult {
  /// #N particles, level by level (0-cells, then 1-cells, then 2-cells).
  std::vector<Vec3> positions;
  /// #N: 2-cells: unit normal from label_a into label_b; zero otherwise.
  std::vector<Vec3> normals;
  std::vector<int> junction;                  ///< #N: number of materials (4 point, 3 curve, 2 surface)
  std::vector<std::array<int, 4>> labels;     ///< #N: label values ascending, -1 unused
  std::vector<double> spacing;                ///< #N: local spacing h, world units
  std::vector<double> energy;                 ///< #N: particle energy E_i (σ = 1 units)
  std::vector<double> residual;               ///< #N: max |f_a - f_b| over the cell at the particle
  std::array<MultiLevelStats, 3> levels;
  double max_residual = 0;
  std::uint64_t field_evaluations = 0;
  EngineStats engine;  ///< the engine's counters over all levels (updates, trials, rejections, failures, ...)
  /// Pairs of surface particles of two interfaces sharing a material, closer
  /// than h/4, replaced by one particle on their triple junction.
  std::size_t junction_repairs = 0;
  std::size_t close_pairs_merged = 0;  ///< same-interface pairs closer than h/4 merged into one (repair_junctions)
  /// Pairs of particles of two triple curves sharing two materials, closer
  /// than h/4, replaced by one particle on their quadruple junction ...
  std::size_t corner_repairs = 0;
  std::size_t curve_pairs_dropped = 0;  ///< ... or, where that projection fails, by the first of the two
};

/// Sample every junction of the material set.
///   seeds:  junction seeds (e.g. junction_seeds_from_mesh / _from_materials);
///   sizing: optional h(x) (world units, > 0; must cover the junctions);
///           otherwise params.spacing.
/// \throw InputError for fewer than 2 materials, materials whose domains do
///   not overlap, a non-finite seed, no seed at all, no interface found
///   (labels that never touch); UsageError for spacing <= 0 without sizing,
///   or bad parameters.
MultiParticleResult distribute_multi_particles(const MaterialSet& m, const std::vector<JunctionSeed>& seeds,
                                               const SizingField* sizing, const MultiParticleParams& params);

/// The result as a point set: normals, vertex scalars junction, label_a ..
/// label_d, spacing, energy, residual.
Mesh multi_particles_mesh(const MultiParticleResult& r);

}  // namespace pm
