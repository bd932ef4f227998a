#pragma once
// The one particle engine of libcore (SPEC §3, Meyer 2008 Chapters 3-7):
// particles constrained to a set (a surface, a junction curve, an element's
// reference space, a volume) relax with a compact pair energy until they
// settle in a near-hexagonal (or, in volumes, near-close) packing.
//
// The seam. A *constraint* C says what a particle is constrained to:
//   * the state a particle carries (C::State: a gradient, a junction cell,
//     an element id and reference coordinates, ...) next to its world point
//     and normal (SamplePoint<State>);
//   * place(): project a world point onto the set (seeds, split children);
//   * tangent() / move(): the tangent-space part of a move and its
//     re-projection;
//   * dimension(), ideal_neighbours(), split_below(), delete_above(): the
//     ideal energy n E(β) and the population thresholds of a particle;
//   * children(): where the particles of a split go;
//   * sees() / same_cell(): which particles interact and which pairs are
//     normal-weighted (culling far sides of thin parts).
// The engine owns the rest: pair energies and normal weighting, the pair
// scale α_ij (uniform, curvature-adaptive or sizing field, per-type
// factors), the counter RNG, bins and their 8-colour parallel Gauss-Seidel
// sweeps, cached neighbour lists, the adaptive step, population control,
// fixed particles (lower levels), coarse-to-fine, convergence, statistics
// and progress.
//
// The engine is a template over the constraint (static polymorphism: the
// inner loops call the constraint without virtual dispatch); it is
// instantiated in the constraint's .cpp file (sample/surface_constraint.cpp,
// sample/junction_constraint.cpp, ...), so only those compile this header's
// template code.
//
// Scale convention (pm/sample/particles.h): r_ij = α_ij (x_i - x_j), σ = 1,
//   curvature mode: α_ij = β (1 + ρ s C_ij / (2π)) / (k s), capped;
//   sizing mode:    α_ij = β / (k min(h_i, h_j)), floored;
// β = 0.5/cos(π/6), k the coarse-to-fine / fixed-count scale; typed
// particles divide α_ij by the type pair's distance factor t(T_i, T_j).
//
// Determinism: particles are processed Gauss-Seidel in bin order; bins are
// coloured (bx%2, by%2, bz%2) and only bins of one colour run in parallel
// (>= 2 bins apart: none reads what another writes), so the result is
// bit-identical for any thread count. Randomness is a counter-based hash of
// (seed, particle id, iteration, stream).
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <type_traits>
#include <vector>

#include "pm/base/log.h"
#include "pm/base/parallel.h"
#include "pm/base/stats.h"
#include "pm/base/vec.h"
#include "pm/field/sizing.h"

namespace pm {

enum class ParticleEnergy {
  cotangent,  ///< modified cotangent, E = cot(π|r|/2) + π|r|/2 - π/2 (default)
  radial,     ///< radial, E = (1/|r|)(1 - |r|)²
};

/// Ideal energy of one surface particle, 6 E(β) (hexagonal 1-ring at |r| = β).
double particle_ideal_energy(ParticleEnergy e);

/// cot_fast's polynomial: u = kCotU a² - 1 and g(u) = Σ kCotCoefficients[k] u^k.
constexpr double kCotU = 2.0 / (1.5707963267948966 * 1.5707963267948966);
constexpr double kCotCoefficients[12] = {
    0.3644240924627032,    0.035284612224661914,  0.004786418171844347,  0.0006770200264722433,
    9.651374716101062e-05, 1.3781290994788787e-05, 1.9685840362232052e-06, 2.812227398865763e-07,
    4.011325214527347e-08, 5.727342515802359e-09, 8.723542947382136e-10, 1.2580017844867603e-10};
/// cot(a) for 0 < a <= π/2 without a call to sin and cos: cot a = 1/a - a g(a²)
/// with g(t) = Σ 2^2n |B_2n| t^(n-1) / (2n)! (B the Bernoulli numbers) as a
/// degree-11 polynomial in u = 2t/(π/2)² - 1, fitted at Chebyshev nodes to
/// the series: g is within 2.5e-14, cot within 4e-14 on the whole range
/// (tests/unit/particles_test).
inline double cot_fast(double a) {
  const double u = a * a * kCotU - 1.0;
  double g = kCotCoefficients[11];
  for (int k = 10; k >= 0; --k) g = g * u + kCotCoefficients[k];
  return 1.0 / a - a * g;
}

/// Pair energy E(r) and dE/dr for |r| < 1 (0 beyond); ε_r is not added here.
/// Cotangent: E = cot(πr/2) + πr/2 - π/2, dE/dr = -(π/2) cot²(πr/2).
inline double particle_pair_energy(ParticleEnergy e, double r, double& dE_dr) {
  if (r >= 1.0) {
    dE_dr = 0;
    return 0;
  }
  if (e == ParticleEnergy::radial) {
    dE_dr = 1.0 - 1.0 / (r * r);
    return 1.0 / r - 2.0 + r;
  }
  constexpr double kHalfPi = 1.5707963267948966;
  const double a = kHalfPi * r;
  const double ct = cot_fast(a);
  dE_dr = -kHalfPi * ct * ct;
  return ct + a - kHalfPi;
}

/// The pair loop's arithmetic for n pairs at once: with dist = sqrt(d2[s])
/// and r = al[s] dist + ε_r (kEpsR), ew[s] = w[s] E(r) and, when fs is
/// given, fs[s] = w[s] dE/dr(r) al[s] / dist (0 at dist 0): the pair's force
/// on the first particle is -(x_i - x_j) fs[s]. The cotangent runs four
/// pairs per AVX2 instruction where the CPU has it, with the same operations
/// in the same order as particle_pair_energy (no fused multiply-add): the
/// same bits as the scalar loop. ew and fs have room for n rounded up to a
/// multiple of 4 (the entries past n are scratch).
void particle_pair_terms(ParticleEnergy e, std::size_t n, const double* d2, const double* al, const double* w,
                         double* ew, double* fs);

// ---------------------------------------------------------------------------
// Constants of the particle system, named once (SPEC §3 parameter table).
namespace engine_constants {
constexpr double kPi = 3.14159265358979323846;
constexpr double kEpsR = 1e-7;               ///< added to |r|
constexpr double kGamma = 0.156;             ///< normal weighting threshold
constexpr double kLambda0 = 1.0;             ///< initial step factor
constexpr double kLambdaMin = 1e-14;         ///< below this a particle stays put
constexpr double kLambdaFactor = 10.0;       ///< SPEC's step factor change after a rejected / first-try accepted move
/// Quadratic step control: the next step is this multiple of the minimiser
/// of the parabola fitted along the move (over-relaxation: the fit sees the
/// neighbours standing still, and they move too). Measured against the
/// factor rule (rr mean of the improved surface): 1.5 lost 0.002 on the
/// bunny and the knot, 2 only 0.001 but its skull had a 0.19 triangle at the
/// thin ear bone; 1.75: skull +0.0017, bunny -0.0017, knot -0.0012, and on
/// the 258k brain 1.3, 1.5, 1.7, 2 gave 25.5, 26.3, 23.9, 25.1 updates per
/// particle (factor rule 45.4).
constexpr double kStepOverRelax = 1.75;
/// λ_i <= 100 s_i² (world units² per energy unit): one name for what the two
/// old engines called kLambdaMaxPerS2 and kLambdaMaxPerH2 (both 100).
constexpr double kLambdaMaxPerSpacing2 = 100.0;
constexpr int kPlaceSteps = 20;              ///< projection steps for seeds and new particles
/// Re-projection steps after a tangent move. The old engines used 4 (surface
/// Newton) and 6 (junction Gauss-Newton); 4 is kept for both: the README's
/// measurement shows the same rejected-trial rate and quality with fewer
/// field evaluations (both converge quadratically from a tangent step).
constexpr int kReprojectSteps = 4;
constexpr double kSplitOffset = 0.5;         ///< a split child is placed this many local spacings away
constexpr double kQuadOffset = 0.25;         ///< coarse-to-fine children: ± this many spacings along two tangents
constexpr double kSizingSlack = 1.25;        ///< sizing: pair radius cap = 1.25 × largest h / β
constexpr double kSpacingSlack = 1.5;        ///< a move may grow the local spacing by at most this factor
constexpr int kColours = 8;                  ///< bin colours (bx%2, by%2, bz%2)
/// Sub-bins per axis of surface particles (EngineParams::sub_bins): every
/// bin is sorted into kSubBins³ sub-cells, so that a gather scans only the
/// sub-cells its ball meets (brain mask, 476k particles: 316 -> 66
/// particles scanned per gather for 16 kept; particle stage 22 -> 19 s).
constexpr int kSubBins = 3;
constexpr std::size_t kSerialBelow = 2000;   ///< sweeps of fewer particles run on one thread
constexpr int kQuadRecolourSweeps = 300;   ///< quad packing: sweeps that start with grow_types (EngineParams::recolour_sweeps)
constexpr double kQuadTolerance = 1e-6;    ///< quad packing: default convergence tolerance (a square lattice's shear is soft)
constexpr double kRetypeMargin = 0.02;      ///< quad packing: a particle changes type when that lowers its energy by more
constexpr double kGatherMargin = 0.25;       ///< first gather covers trial moves up to 0.25 s_i
constexpr double kFirstGatherGrowth = 1.1;   ///< ... whose local spacing grew by at most 10%
constexpr double kListSkin = 0.5;            ///< neighbour lists: a particle may drift 0.5 s_i before a rebuild
constexpr double kListsBelowMove = 0.25 * kListSkin;  ///< use lists once the largest move is below this (× s_i)
constexpr double kHoleRadius = 1.5;          ///< an anchor without a particle within 1.5 s_i is a hole
constexpr int kMaxRefills = 4;               ///< refill rounds on the final level
/// Surface particles (EngineParams::first_population_interval): the first
/// population check of a level comes after this many sweeps, the next after
/// twice as many, and so on up to population_interval, so that seeds far
/// from the level's density reach it in a few short rounds (brain mask,
/// 259k particles: 307 -> 255 iterations, 7k mcinit seeds for 16k particles
/// on the coarsest level). A volume packing checked that early crowds.
constexpr int kFirstPopulationInterval = 8;
/// Settled-particle skipping: when more than this share of the particles
/// moved, nobody is settled and the wake-up scan is skipped.
constexpr double kWakeScanShare = 0.25;
/// EngineParams::population_balance: a level that ends on a stationary
/// population relaxes on, without population checks, until the energy
/// changes by less than this × tolerance per sweep (the tail of split/delete
/// churn that it skips also relaxed; without the polish the five ch6 rr
/// means lost 0.001-0.003, with it at most 0.0006).
constexpr double kBalancePolish = 0.25;
constexpr int kMaxTypes = 4;                 ///< particle types (pair scale table is kMaxTypes²)
/// Fixed count: near the hexagonal packing E ∝ s^4.7 (cotangent), hence
/// the exponent 1/5 of the spacing correction, clamped to [1/2, 2].
constexpr double kCountExponent = 0.2, kCountClamp = 2.0, kCountSettled = 0.01;
}  // namespace engine_constants

/// β = 0.5/cos(π/6): the hexagonal 1-ring sits at |r| = β.
double engine_beta();
/// Normal weighting w(n_i · n_j) of SPEC §3 (1 above γ, 0 at or below 0).
inline double normal_weight(double d) {
  using namespace engine_constants;
  if (d > kGamma) return 1.0;
  if (d <= 0) return 0.0;
  return std::cos(0.5 * kPi * (kGamma - d) / kGamma);
}
/// Counter-based uniform number in [0, 1) of (seed, id, iteration, stream).
double counter_uniform(std::uint64_t seed, std::uint64_t id, std::uint64_t iter, std::uint64_t stream);
std::uint64_t mix64(std::uint64_t z);
/// A unit tangent basis (t1, t2) of the plane normal to the unit vector n.
void tangent_basis(const Vec3& n, Vec3& t1, Vec3& t2);
/// The tangent-plane offset of length dist at `angle` in tangent_basis(n).
Vec3 tangent_offset(const Vec3& n, double angle, double dist);
/// Four offsets ±a ± b in the tangent plane of n, a and b orthogonal of
/// length dist turned by theta (coarse-to-fine children). Returns 4.
int quad_children(const Vec3& n, double theta, double dist, Vec3* out);
/// Greedy thinning in input order: point i is dropped when a kept point of
/// its group (group[i]; empty = one group) lies closer than radius[i]
/// (world units). Returns the kept indices, ascending. Deterministic.
std::vector<std::size_t> thin_points(const std::vector<Vec3>& x, const std::vector<double>& radius,
                                     const std::vector<std::int32_t>& group);
/// "%.6g" and "(x, y, z)" for messages.
std::string engine_fmt(double v);
std::string engine_fmt(const Vec3& v);

/// Random streams of the engine's counter RNG.
enum EngineStream : std::uint64_t {
  kStreamPopulation = 1, kStreamSplitDir, kStreamInitX, kStreamInitY, kStreamInitZ, kStreamQuad,
  kStreamType
};

/// Why a constraint could not project a point.
enum class ProjectFailure : int {
  none = 0,
  non_finite,      ///< the field is not finite at an iterate
  flat,            ///< zero (or singular) gradient
  left_domain,     ///< an iterate left the domain
  no_convergence,  ///< not within tolerance after the allowed steps
  not_dominant,    ///< junction: another material is above the cell's
  outside_sizing,  ///< the sizing field does not cover the point
  count_
};
const char* project_failure_name(ProjectFailure f);

/// Book-keeping of one projection: field evaluations and the failure reason.
struct Probe {
  std::uint64_t evaluations = 0;
  ProjectFailure why = ProjectFailure::none;
  bool fail(ProjectFailure f) {
    why = f;
    return false;
  }
};

/// A particle's constrained position: world point, unit normal (surfaces) or
/// frame (curve tangent), and the constraint's own state.
template <class State>
struct SamplePoint {
  Vec3 x;
  Vec3 n;
  State s{};
};

/// Counters of a run, shared by every configuration of the engine.
struct EngineStats {
  std::uint64_t updates = 0;            ///< particle updates (an energy + force evaluation, then trials)
  std::uint64_t trials = 0;             ///< trial positions evaluated
  std::uint64_t rejected = 0;           ///< trials rejected (energy up, off the constraint, too long)
  std::uint64_t settled_skips = 0;      ///< updates skipped because the particle's neighbourhood settled
  std::uint64_t field_evaluations = 0;  ///< field / constraint evaluations
  std::uint64_t list_builds = 0;
  /// Updates whose neighbour gather was redone wider: a trial reached beyond the first one
  std::uint64_t regathers = 0;
  std::uint64_t place_failures = 0;     ///< seeds and new particles the constraint could not place (dropped)
  std::uint64_t trial_failures = 0;     ///< trial moves the constraint could not re-project (step shrinks)
  std::uint64_t failures_by_reason[int(ProjectFailure::count_)] = {};  ///< place + trial failures
  /// Particle updates in which the constraint could not project a single
  /// trial down to λ_min (the particle stays where it is; the run goes on).
  std::uint64_t stuck = 0;
  std::uint64_t first_stuck_id = ~std::uint64_t(0);  ///< the smallest id stuck in the first sweep with any
  std::string first_failure;            ///< "particle N at (x, y, z): reason" (empty when none)
  double seconds_relax = 0;             ///< wall-clock seconds in sweeps (updates/s = updates / seconds_relax)
  double seconds_population = 0;
};

/// Add the per-update counters of `from` (updates, trials, rejected,
/// settled skips, field evaluations, place and trial failures, stuck,
/// failures by reason) to `into`.
void add_update_counters(EngineStats& into, const EngineStats& from);

/// The counters as a JSON object for --stats (updates, trials,
/// rejected_trials, field_evaluations, updates_per_second, ...).
Json engine_stats_json(const EngineStats& s);
/// One line for a warning when particles could not be projected, else empty.
std::string engine_failure_summary(const EngineStats& s);

/// How a particle's step λ_i changes after a trial (SPEC §3, adaptive step).
/// `factor` is the dissertation's rule: ×step_factor after a first-try
/// acceptance, ÷step_factor after a rejection. `quadratic` fits
/// e(λ) = e_0 - gλ + cλ² through the trial (g = v·v_t, the slope of the
/// energy along the move at λ = 0) and takes kStepOverRelax times its
/// minimiser g/2c, kept within [λ/f, λf] after an acceptance and [λ/f, λ/2]
/// after a rejection (f = step_factor); a trial on a concave stretch (c <= 0)
/// grows λ by f. `particles` on surfaces uses it by default: it halves the
/// updates per particle on the folded brain mask and packs better there, and
/// within 0.002 of rr mean on the smooth shapes. The others keep the factor
/// rule: multiparticles' junction cells took 2-3x as long with rr means down
/// by 0.005 (frog5, frog15); with volume packing the ball's free particles
/// came within 0.37 s of the fixed boundary (0.4 s required); reference-space
/// particles' spacing on Tet_channel_m3 varied more (cv 0.108 > 0.1).
enum class StepControl { factor, quadratic };

/// The quadratic rule's next step after a trial of step `lambda` changed the
/// energy by `de`, where the energy's slope along the move is -`slope` (> 0):
/// kStepOverRelax times the minimiser of e_0 - slope λ + cλ², clamped to
/// [lo, hi]; hi when the parabola has no minimum (c <= 0).
inline double quadratic_step(double lambda, double slope, double de, double lo, double hi) {
  const double c = (de + slope * lambda) / (lambda * lambda);
  if (!(c > 0)) return hi;
  return std::min(std::max(engine_constants::kStepOverRelax * slope / (2 * c), lo), hi);
}

/// How the engine turns a particle into a local spacing (see the scale
/// convention above).
struct EngineParams {
  ParticleEnergy energy = ParticleEnergy::cotangent;
  double tolerance = 0.0015;
  int max_iters = 2000;
  int population_interval = 50;
  /// The first population check of a level after this many sweeps, then
  /// twice as many each time up to population_interval (0 = every
  /// population_interval sweeps).
  int first_population_interval = 0;
  double population_tolerance = 0.001;
  /// The final population check also ends the level when the population is
  /// stationary: splits and deletions balance within population_tolerance
  /// × N and at most as many particles lie outside the thresholds for every
  /// draw of the random bias (E < split_below E_ideal, or E / 2 >
  /// delete_above E_ideal). Near the junctions of a label map a few dozen
  /// particles sit near the thresholds for good, and each check draws a
  /// different few to split or delete; requiring fewer changes than the
  /// tolerance then waits for a lucky draw (frog5 surfaces: 13-47 more
  /// sweeps of that churn). The level then relaxes on to kBalancePolish ×
  /// tolerance without population checks.
  bool population_balance = false;
  bool population_control = true;
  std::uint64_t seed = 1;
  bool progress = true;
  /// Curvature mode (spacing s, density ρ, alpha_cap) when sizing_mode is
  /// false; else sizing mode with h(x) from `sizing` or the constant
  /// `spacing` when sizing is null.
  bool sizing_mode = false;
  const SizingField* sizing = nullptr;
  double spacing = 0, density = 0, alpha_cap = 10;
  /// A deleted particle must leave a staying particle of its cell within its
  /// interaction radius (keeps short curves populated).
  bool keep_covered = false;
  /// Per-type pair distance factors t(a, b) (symmetric), see set_types().
  int types = 1;
  /// Two-type checkerboards (set_quad_types): a population split makes a
  /// particle of the other type (the nearest neighbour of a checkerboard
  /// square is unlike), and the coarse-to-fine split's 4 square corners
  /// alternate their types.
  bool alternate_types = false;
  /// Two-type checkerboards: before each of the first `recolour_sweeps`
  /// sweeps (counted over all levels), colour the packing again as one
  /// growing grain (grow_types), so that the positions follow one colouring
  /// instead of freezing into small grains of opposite phase.
  int recolour_sweeps = 0;
  /// Neighbours of the ideal packing for the ideal energy (0 = the
  /// constraint's: 6 on a surface); a checkerboard of two types has 8 at
  /// r = β (4 unlike, 4 like on the diagonals).
  double ideal_neighbours = 0;
  double type_scale[engine_constants::kMaxTypes][engine_constants::kMaxTypes] = {{1, 1, 1, 1}, {1, 1, 1, 1},
                                                                                 {1, 1, 1, 1}, {1, 1, 1, 1}};
  /// Skip updating a particle whose last accepted move was shorter than
  /// this fraction of its spacing and near which no particle moved more than
  /// its own fraction (within that particle's reach), re-checking it every
  /// `settled_recheck` sweeps (0 = off).
  double settled_move = 0;
  int settled_recheck = 8;
  int reproject_steps = engine_constants::kReprojectSteps;  ///< constraint steps after a tangent move
  /// λ_i is multiplied by this after a first-try acceptance and divided by
  /// it after a rejection (> 1; SPEC: 10). Smaller factors follow the step
  /// that fits more closely but freeze more packing defects: 3 took the
  /// 259k-particle brain mask from 53 to 30 updates per particle (rr mean
  /// 0.9739 both), but the bunny's and the knot's distance fields from 140
  /// to 153 and 84 to 96, their rr means down by 0.003-0.004.
  double step_factor = engine_constants::kLambdaFactor;
  StepControl step_control = StepControl::factor;
  /// Strongly graded spacings (volume packing): besides the bins, which are
  /// as wide as the largest interaction radius, keep a finer grid from
  /// which particles with a short reach gather their neighbours.
  bool fine_bins = false;
  /// Sub-cells per bin axis (1 = none; engine_constants::kSubBins for large
  /// surface samplings, where bins hold tens of particles). Ignored with
  /// fine_bins. The sub-cells order the particles within a bin, so the
  /// result differs (deterministically) with the setting.
  int sub_bins = 1;
};

/// Copy the relaxation settings every configuration's params struct names
/// alike (energy, tolerance, max_iters, population_interval,
/// population_tolerance, seed, progress, settled_move, reproject_steps,
/// step_factor, step_control).
template <class P>
void copy_relax_params(const P& p, EngineParams& e) {
  e.energy = p.energy;
  e.tolerance = p.tolerance;
  e.max_iters = p.max_iters;
  e.population_interval = p.population_interval;
  e.population_tolerance = p.population_tolerance;
  e.seed = p.seed;
  e.progress = p.progress;
  e.settled_move = p.settled_move;
  e.reproject_steps = p.reproject_steps;
  e.step_factor = p.step_factor;
  e.step_control = p.step_control;
}

/// The rules of particles on a 2-manifold in world space (hexagonal
/// packing): a mix-in for constraints whose SamplePoint normal is the unit
/// surface normal.
struct SurfaceRules {
  template <class P> int dimension(const P&) const { return 2; }
  template <class P> double ideal_neighbours(const P&) const { return 6; }
  template <class P> double split_below(const P&) const { return 0.35; }
  template <class P> double delete_above(const P&) const { return 1.75; }
  /// A point `dist` away in the tangent plane at angle 2πu.
  template <class P> Vec3 split_offset(const P& p, double u, double dist) const {
    return tangent_offset(p.n, 2 * engine_constants::kPi * u, dist);
  }
  /// Coarse-to-fine: the 4 quad_children of the tangent plane.
  template <class P> int children(const P& p, double theta, double dist, Vec3* out) const {
    return quad_children(p.n, theta, dist, out);
  }
  template <class P> Vec3 tangent(const P& p, const Vec3& v) const { return v - p.n * dot(p.n, v); }
  template <class P> bool sees(const P&, const P&, bool) const { return true; }
  template <class P> bool weighted(const P&) const { return true; }
  template <class P> bool same_cell(const P&, const P&) const { return true; }
  /// sees, weighted and same_cell ignore the pair: the engine may copy a
  /// neighbour's pair data from a per-particle cache (see kPairFree).
  static constexpr bool kPairFree = true;
};

/// Whether constraint C declares kPairFree (its pair rules depend on no
/// particle's state); false when it does not say.
template <class C, class = void>
struct pair_free : std::false_type {};
template <class C>
struct pair_free<C, std::void_t<decltype(C::kPairFree)>> : std::integral_constant<bool, C::kPairFree> {};

/// Whether constraint C declares kKeyedPairs: its pair rules depend on one
/// integer of the other particle, pair_key(o) (e.g. a junction cell), and
/// its fixed flag: sees(i, o, fixed) == sees_key(i, pair_key(o), fixed) and
/// weighted(i) && same_cell(i, o) == weighted_key(i, pair_key(o)).
template <class C, class = void>
struct keyed_pairs : std::false_type {};
template <class C>
struct keyed_pairs<C, std::void_t<decltype(C::kKeyedPairs)>> : std::integral_constant<bool, C::kKeyedPairs> {};

/// Distance factors for two-type quad packing (Meyer 2008, Chapter 7):
/// like pairs sit √2 farther apart than unlike pairs (the diagonal of a
/// checkerboard square), t(a, a) = √2, t(a, b) = 1; splits alternate the
/// types and the ideal packing has 8 neighbours.
void set_quad_types(EngineParams& p);

/// Uniform bins of one width over a point set, the 3x3x3 block of every
/// bin, and the 8 colour classes of the bins holding active points.
class SampleBins {
 public:
  /// Sorts the points into bins of width >= w, and within a bin into
  /// sub³ sub-cells (z, then y, then x); order() maps new index -> old index
  /// (stable within a sub-cell). `active` (#N or empty = all) marks points
  /// that will be updated: only bins holding one are coloured.
  void build(const std::vector<Vec3>& x, double w, const std::vector<char>& active, int sub = 1);
  const std::vector<std::uint32_t>& order() const { return order_; }
  std::size_t cells() const { return cell_key_.size(); }
  std::uint32_t begin(std::size_t c) const { return cell_start_[c]; }
  std::uint32_t end(std::size_t c) const { return cell_start_[c + 1]; }
  const std::int32_t* block(std::size_t c) const { return &cell_nbr_[c * 27]; }
  std::uint32_t colour_begin(int k) const { return colour_start_[std::size_t(k)]; }
  std::uint32_t colour_end(int k) const { return colour_start_[std::size_t(k) + 1]; }
  std::uint32_t colour_cell(std::uint32_t k) const { return colour_cells_[k]; }
  /// Per axis, bit 0/1/2: the -1/0/+1 neighbour of cell c may hold a point
  /// within `slack` of x. Combined as mask >> (k%3), >> (k/3%3), >> (k/9).
  void axis_masks(std::size_t c, const Vec3& x, double slack, int m[3]) const;
  /// Cell holding x, or -1 (x outside the grid or an empty bin); the 3x3x3
  /// block of that bin position (cells may be -1).
  bool block_of(const Vec3& x, std::int32_t out[27]) const;
  double width() const { return w_; }
  /// Calls f(begin, end) for the index ranges of cell c's points binned in
  /// a sub-cell that meets the box x ± r: a superset of the points binned
  /// within r of x, one range per sub-cell row, in a fixed order.
  template <class F>
  void visit_box(std::size_t c, const Vec3& x, double r, F&& f) const {
    const int S = sub_;
    int s0[3], s1[3];
    for (int a = 0; a < 3; ++a) {
      // Sub-cell coordinates of the box, widened by a hair (far above the
      // rounding of the product) so that rounding never drops a point on a
      // sub-cell face; the border cells are open.
      const double c0 = cell_lo_[c][a];
      const double t0 = (x[a] - r - c0) * inv_ws_ - 1e-9, t1 = (x[a] + r - c0) * inv_ws_ + 1e-9;
      if (t1 < 0 || t0 >= S) return;
      s0[a] = t0 < 0 ? 0 : int(t0);
      s1[a] = t1 >= S - 1 ? S - 1 : int(t1);
    }
    const std::uint32_t* st = &sub_start_[c * std::size_t(S * S * S + 1)];
    for (int k = s0[2]; k <= s1[2]; ++k)
      for (int j = s0[1]; j <= s1[1]; ++j) {
        const int row = S * (j + S * k);
        const std::uint32_t b = st[row + s0[0]], e = st[row + s1[0] + 1];
        if (b < e) f(b, e);
      }
  }

 private:
  std::int32_t find(std::uint64_t key) const;
  std::vector<std::uint64_t> keys_, keys_tmp_;
  std::vector<std::uint32_t> order_, order_tmp_, radix_count_;
  std::vector<std::uint64_t> cell_key_;
  std::vector<Vec3> cell_lo_;  // per cell, its lower corner
  std::vector<std::uint32_t> cell_start_, sub_start_;
  std::vector<std::int32_t> cell_nbr_;
  std::vector<std::uint32_t> hash_;
  std::vector<std::uint32_t> colour_start_, colour_cells_;
  std::uint64_t nx_ = 0, ny_ = 0, nz_ = 0;
  Vec3 lo_;
  double w_ = 1, inv_ws_ = 1;  // bin width, sub-cells per world unit
  int sub_ = 1;
};

/// A dense grid of cubic cells over a point set's box, for gathers whose
/// radius varies from point to point: the cells of one x row are adjacent in
/// order(), so a ball is visited as one index range per row it crosses.
class DenseBins {
 public:
  /// Cells of width >= w, widened until there are at most max_cells.
  void build(const std::vector<Vec3>& x, double w, std::size_t max_cells);
  double width() const { return w_; }
  /// Calls f(begin, end) over runs of point indices: every point binned in
  /// a cell that meets the ball of radius r around x (a superset of the
  /// points within r), in a fixed order (rows by z then y, cells by x, points
  /// by index), one run per row the ball crosses.
  template <class F>
  void visit_ball_ranges(const Vec3& x, double r, F&& f) const {
    if (start_.empty()) return;
    const double r2 = r * r;
    const long iz0 = clamp_cell(x.z - r, 2), iz1 = clamp_cell(x.z + r, 2);
    const long iy0 = clamp_cell(x.y - r, 1), iy1 = clamp_cell(x.y + r, 1);
    for (long iz = iz0; iz <= iz1; ++iz) {
      const double dz = axis_gap(x.z, iz, 2), rz = r2 - dz * dz;
      if (rz < 0) continue;
      for (long iy = iy0; iy <= iy1; ++iy) {
        const double dy = axis_gap(x.y, iy, 1), ry = rz - dy * dy;
        if (ry < 0) continue;
        const double hw = std::sqrt(ry);
        const long ix0 = widened_cell(x.x - hw, -kWiden), ix1 = widened_cell(x.x + hw, kWiden);
        const std::size_t row = std::size_t(n_[0]) * (std::size_t(iy) + std::size_t(n_[1]) * std::size_t(iz));
        const std::uint32_t b = start_[row + std::size_t(ix0)], e = start_[row + std::size_t(ix1) + 1];
        if (b < e) f(order_.data() + b, order_.data() + e);
      }
    }
  }

 private:
  // The x cell of v by a multiplication instead of clamp_cell's division,
  // moved by `widen` cells first: with |widen| far above the rounding of
  // either, the row's range can only grow (a superset: the same points in
  // range, in the same order).
  static constexpr double kWiden = 1e-6;
  long widened_cell(double v, double widen) const {
    const double t = (v - lo_[0]) * inv_w_ + widen;
    return t < 0 ? 0 : t >= double(n_[0] - 1) ? n_[0] - 1 : long(t);
  }
  // floor((v - lo) / w) clamped to the grid; no floor needed: below 0 and
  // at or above the last cell clamp alike, and in between truncation is floor.
  long clamp_cell(double v, int a) const {
    const double t = (v - lo_[a]) / w_;
    return t < 0 ? 0 : t >= double(n_[a] - 1) ? n_[a] - 1 : long(t);
  }
  // Distance from v to cell i's slab along axis a (0 inside).
  double axis_gap(double v, long i, int a) const {
    const double c0 = lo_[a] + double(i) * w_;
    return v < c0 ? c0 - v : v > c0 + w_ ? v - c0 - w_ : 0.0;
  }
  std::vector<std::uint32_t> start_, order_, cell_of_;
  long n_[3] = {0, 0, 0};
  Vec3 lo_;
  double w_ = 1, inv_w_ = 1;
};

/// The engine. C is a constraint as described above.
template <class C>
class ParticleEngine {
 public:
  using State = typename C::State;
  using Point = SamplePoint<State>;

  struct Particle {
    Point p;
    double attr = 0;     // curvedness (curvature mode) or h(x) (sizing mode)
    double spacing = 0;  // local spacing β/α_ii (also the step cap)
    double lambda = engine_constants::kLambda0;
    double energy = 0;
    double delta = 0;    // energy change of the last move (<= 0)
    double moved = 0;    // length of the last move / spacing
    std::uint64_t id = 0;
    std::int32_t neighbours = 0;
    std::uint8_t type = 0;
    bool fixed = false;
    std::uint16_t quiet = 0;  // sweeps since the particle last moved more than settled_move
  };

  /// A point to place: where, like which particle (the constraint's state,
  /// e.g. the junction cell), of which type.
  struct Candidate {
    Vec3 x;
    Point like;
    std::uint8_t type = 0;
  };

  ParticleEngine(const C& c, const EngineParams& p);

  // --- population -------------------------------------------------------
  /// Place candidates in parallel (up to `steps` constraint steps, each
  /// step at most max_step[i] long when given); ok[i] says which succeeded,
  /// placed[i] the result. Outside the sizing field's box counts as failed
  /// with reason outside_sizing (outside[i] = 1).
  void place_many(const std::vector<Candidate>& cands, int steps, const std::vector<double>& max_step,
                  std::vector<Point>& placed, std::vector<char>& ok, std::vector<char>* outside = nullptr);
  /// Append a particle at a placed point; returns its index.
  std::size_t add(const Point& q, std::uint8_t type = 0, bool fixed = false);
  void fix_all() {
    for (Particle& q : parts_) q.fixed = true;
  }
  std::size_t active_count() const;
  /// The projected initial points become anchors: on the final level every
  /// anchor keeps a particle within kHoleRadius local spacings.
  void set_anchors_from_particles() { anchors_ = parts_; }
  void guard_anchors() { guard_anchors_ = true; }
  std::size_t refill_holes();

  // --- scale ------------------------------------------------------------
  void set_scale(double k);
  /// The convergence tolerance of the next relax() calls.
  void set_tolerance(double t) { p_.tolerance = t; }
  void set_population_tolerance(double t) { p_.population_tolerance = t; }
  double scale() const { return scale_; }
  double planar_spacing() const { return s_; }
  void refresh_spacings() {
    for (Particle& q : parts_) q.spacing = local_spacing(q.attr, q.type);
  }
  /// Start near the target density: keep particles (in order) none of which
  /// lies within `factor` × its spacing of an earlier kept one (thin_points).
  /// Returns how many were dropped.
  std::size_t thin_particles(double factor) {
    std::vector<Vec3> xs(parts_.size());
    std::vector<double> radius(parts_.size());
    for (std::size_t i = 0; i < parts_.size(); ++i) {
      xs[i] = parts_[i].p.x;
      radius[i] = factor * parts_[i].spacing;
    }
    const std::vector<std::size_t> keep = thin_points(xs, radius, {});
    std::vector<Particle> kept;
    kept.reserve(keep.size());
    for (std::size_t i : keep) kept.push_back(parts_[i]);
    const std::size_t dropped = parts_.size() - kept.size();
    parts_.swap(kept);
    return dropped;
  }

  // --- relaxation -------------------------------------------------------
  struct LevelResult {
    bool converged = false;
    int iterations = 0;
    std::size_t splits = 0, deletions = 0, refilled = 0;
  };
  /// Relax the active particles until the energy converges with a stable
  /// population (population control or, with fixed_count, the spacing scale).
  LevelResult relax(const std::string& label, bool fixed_count);
  /// Coarse-to-fine: replace every particle by its constraint children
  /// (placed), then halve the scale.
  void split_all();
  /// Fresh (Jacobi) energies and neighbour counts; returns Σ E_i over the
  /// active particles.
  double measure();
  void settle_marks();
  /// Two-type checkerboards (EngineParams::alternate_types): every active
  /// particle takes the type with the lower energy among its neighbours (bin
  /// colours in turn, so deterministic); returns the number that changed.
  std::size_t retype();
  /// Two-type checkerboards: colour the whole packing again as one growing
  /// grain, so that it does not freeze into many small grains of opposite
  /// phase. Each pair within reach prefers to be unlike by
  /// w_ij = E(like) - E(unlike) >= 0; starting from the first particle, the
  /// untyped particle with the largest sum of w_ij towards typed ones is typed
  /// next (as Prim's tree grows), taking the type that is unlike the larger
  /// weight. Unless `force`, the new colouring is kept only when the weight of
  /// its like pairs is lower by kRetypeMargin. Sequential and deterministic;
  /// returns the number that changed.
  std::size_t grow_types(bool force);

  // --- access -----------------------------------------------------------
  /// Reorder the particles stably by key(particle) (ascending).
  template <class Key>
  void stable_order(Key key) {
    std::stable_sort(parts_.begin(), parts_.end(),
                     [&](const Particle& a, const Particle& b) { return key(a) < key(b); });
  }
  /// Positions, normals, energies and local spacings (#N each) in the
  /// current order.
  void export_points(std::vector<Vec3>& x, std::vector<Vec3>& n, std::vector<double>& energy,
                     std::vector<double>& spacing) const {
    const std::size_t count = parts_.size();
    x.resize(count);
    n.resize(count);
    energy.resize(count);
    spacing.resize(count);
    for (std::size_t i = 0; i < count; ++i) {
      x[i] = parts_[i].p.x;
      n[i] = parts_[i].p.n;
      energy[i] = parts_[i].energy;
      spacing[i] = parts_[i].spacing;
    }
  }
  std::vector<Particle>& particles() { return parts_; }
  const std::vector<Particle>& particles() const { return parts_; }
  const EngineStats& stats() const { return st_; }
  EngineStats& stats() { return st_; }
  std::uint64_t iteration() const { return iteration_; }
  const C& constraint() const { return c_; }
  /// Ideal energy n E(β) of particle q.
  double ideal_energy(const Particle& q) const {
    return (p_.ideal_neighbours > 0 ? p_.ideal_neighbours : c_.ideal_neighbours(q.p)) * e_beta_;
  }
  /// Pair scale α_ij of two particles.
  double pair_alpha(const Particle& a, const Particle& b) const {
    return alpha(a.attr, b.attr, a.type, b.type);
  }
  /// Bins over the current particles (valid after measure()/rebin()) and a
  /// scan of the particles within `r` of x: f(index) for each.
  /// Scans only the bins and sub-cells that meet the box x ± (r + the
  /// largest move in the block since the binning): the same indices in the
  /// same order as a scan of the whole 3x3x3 block (a bin's particles are
  /// sorted by sub-cell, x fastest, as visit_box visits them).
  template <class F>
  void for_each_near(const Vec3& x, double r, F&& f) const {
    std::int32_t block[27];
    if (!bins_.block_of(x, block)) return;
    double moved = 0;
    for (int k = 0; k < 27; ++k)
      if (block[k] >= 0) moved = std::max(moved, bin_moved_[std::size_t(block[k])]);
    const double r2 = r * r, pad = r + moved;
    for (int k = 0; k < 27; ++k) {
      if (block[k] < 0) continue;
      bins_.visit_box(std::size_t(block[k]), x, pad, [&](std::uint32_t b, std::uint32_t e) {
        for (std::uint32_t q = b; q < e; ++q)
          if (norm2(pos_[q] - x) < r2) f(std::size_t(q));
      });
    }
  }
  void rebin(bool for_lists = false);

 private:
  // A neighbour as the pair energy needs it: one cache line.
  struct alignas(64) Cand {
    Vec3 x, n;
    // sizing mode: β/(k h_j), so that α_ij = max(part_i, part_j, floor)
    // without a division; otherwise the adaptivity attribute (curvedness).
    double a;
    std::uint8_t type;
    bool weighted;
    bool fixed;         // keyed constraints: the pair rules' inputs (see keyed_pairs)
    std::int32_t key;
  };

  double alpha(double ai, double aj, std::uint8_t ti, std::uint8_t tj) const {
    double a;
    if (!p_.sizing_mode) {
      a = std::min(beta_ * (1.0 + k_curv_ * 0.5 * (ai + aj)) / s_, alpha_cap_);
    } else {
      a = std::max(beta_ / (scale_ * std::min(ai, aj)), alpha_floor_);
    }
    return typed_ ? a / p_.type_scale[ti][tj] : a;
  }
  double local_spacing(double attr, std::uint8_t type) const {
    (void)type;
    if (!p_.sizing_mode) return beta_ / std::min(beta_ * (1.0 + k_curv_ * attr) / s_, alpha_cap_);
    return scale_ * attr;
  }
  // Upper bound on the interaction radius 1/α_ij of a particle with local
  // spacing `spacing` and any partner (curvature mode: 2 s_i with density,
  // s otherwise; sizing: min(h_i, h_j) <= h_i), times the largest type factor.
  double radius_bound(double spacing) const {
    return std::min(r_max_, (need_curvature_ ? 2.0 : 1.0) * spacing / beta_) * type_max_;
  }
  bool varying() const { return need_curvature_ || p_.sizing_mode; }
  // The adaptivity attribute of a placed point; false outside the sizing field.
  bool attribute(const Point& q, double& a) const {
    if (!p_.sizing_mode) {
      a = need_curvature_ ? c_.curvedness(q) : 0.0;
      return true;
    }
    if (!p_.sizing) {
      a = p_.spacing;
      return true;
    }
    return p_.sizing->sample(q.x, a) && a > 0;
  }
  Particle make(const Point& q, double attr, std::uint64_t id, std::uint8_t type) const;

  double energy_at(const Vec3& x, const Vec3& n, double a, std::uint8_t t, const std::vector<Cand>& cs, Vec3* v,
                   int* nbrs) const;
  Cand cand_of(const Particle& i, const Particle& o) const {
    std::int32_t key = 0;
    if constexpr (kKeyed) key = c_.pair_key(o.p);
    return {o.p.x,  o.p.n, p_.sizing_mode ? beta_ / (scale_ * o.attr) : o.attr,
            o.type, c_.weighted(i.p) && c_.same_cell(i.p, o.p), o.fixed, key};
  }
  // Pair-free and keyed constraints: every particle's Cand, kept with parts_
  // from the binning on (gathers copy one cache line instead of reading the
  // particle); a keyed constraint's pair rules read the cached key.
  static constexpr bool kCached = pair_free<C>::value;
  static constexpr bool kKeyed = !kCached && keyed_pairs<C>::value;
  void cache(std::size_t q) {
    if constexpr (kCached || kKeyed) cands_[q] = cand_of(parts_[q], parts_[q]);
  }
  // Appends q's Cand as seen from i (pair-free constraints: from the cache;
  // keyed: from the cache, weighted for the pair).
  void push_neighbour(std::vector<Cand>& out, const Particle& i, std::size_t q) const {
    if constexpr (kCached) {
      (void)i;
      out.push_back(cands_[q]);
    } else if constexpr (kKeyed) {
      out.push_back(cands_[q]);
      out.back().weighted = c_.weighted_key(i.p, cands_[q].key);
    } else {
      out.push_back(cand_of(i, parts_[q]));
    }
  }
  bool sees(const Particle& i, const Particle& o) const { return c_.sees(i.p, o.p, o.fixed); }
  // sees(i, parts_[q]), from the cache where the constraint is keyed.
  bool sees_index(const Particle& i, std::size_t q) const {
    if constexpr (kKeyed)
      return c_.sees_key(i.p, cands_[q].key, cands_[q].fixed);
    else
      return sees(i, parts_[q]);
  }
  void gather(const Vec3& x, double reach, std::size_t self, std::size_t cell, std::vector<Cand>& out) const;
  void gather_list(const Vec3& x, double reach, std::size_t self, std::vector<Cand>& out) const;
  // Appends the Cands of particles id(0), .., id(count - 1) within sqrt(r2)
  // of x that are not `self` and that P sees, in that order.
  template <class Id>
  void take_in_reach(std::size_t count, Id id, const Vec3& x, double r2, std::size_t self, const Particle& P,
                     std::vector<Cand>& out) const;
  void update(std::size_t i, std::size_t cell, std::vector<Cand>& buf, EngineStats& local);
  void build_lists();
  bool lists_stale() const;
  double sweep(double& energy);
  bool population_control(std::uint64_t tag, bool final_check, LevelResult& lr);
  bool balanced_ = false;  // the last final population check passed on balance (population_balance)
  bool adapt_spacing();
  void build_fine();
  std::int64_t anchor_cover(const Particle& a, const std::vector<char>* dead) const;
  void keep_anchor_covers(std::vector<char>& del, std::size_t& ndel) const;
  void keep_covered(std::vector<char>& del, std::size_t& ndel) const;
  void merge(const EngineStats& local);

  const C& c_;
  EngineParams p_;
  double beta_ = 0, e_beta_ = 0;
  bool need_curvature_ = false, typed_ = false;
  double type_max_ = 1;
  double scale_ = 1, s_ = 0, k_curv_ = 0, alpha_cap_ = 1e300, alpha_floor_ = 0;
  double r_max_ = 0, d_max_ = 0;

  std::vector<Particle> parts_, scratch_, anchors_;
  bool guard_anchors_ = false;
  std::vector<Vec3> pos_;
  std::vector<char> active_, awake_;
  std::uint64_t next_id_ = 0, iteration_ = 0;
  SampleBins bins_;
  // fine_bins: the finer grid (rebuilt before every colour), per bin the
  // longest move of its particles since (how far a candidate can be from
  // where the grid has it), and the fine width (0 = not in use).
  DenseBins fine_;
  std::vector<double> cell_moved_;
  // Per bin, the longest move of its particles since the bins were built
  // (from binned_, their positions then): gather pads its ball by the
  // largest in its 3x3x3 block instead of the largest spacing.
  std::vector<double> bin_moved_;
  std::vector<Vec3> binned_;
  std::vector<Cand> cands_;  // kCached or kKeyed: cand_of(parts_[q], parts_[q])
  double fine_w_ = 0;

  std::vector<std::uint32_t> nbr_start_, nbr_;
  std::vector<Vec3> list_x_;
  std::vector<double> list_s_;
  bool lists_valid_ = false, use_lists_ = false;
  double max_move_ = 1e300;

  tbb::enumerable_thread_specific<std::vector<Cand>> tls_;
  tbb::enumerable_thread_specific<EngineStats> tls_stats_;
  EngineStats st_;
};

}  // namespace pm
