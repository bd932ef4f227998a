#pragma once
// Particles on an isosurface u = c of a high-order (spectral/hp) Nektar++
// field, living in each element's reference space (SPEC §4, Meyer 2008
// Chapter 4; issue #18). A particle's state is (element, xi); the value and
// gradient come from the element's own polynomial (ReferenceField::sample:
// a Nektar++ HpField or the analytic TeardropField), the
// world position and Jacobian J = dT/dxi from the element's geometry, the
// world normal from J^-T grad_xi u.
//
// Moves: the engine's world tangent move v is pulled back, dxi = K v
// (K = J^-1), and the point is projected back onto u = c by Newton on the
// element polynomial in reference coordinates. The Newton correction is
// the minimum-norm one in world space, dxi = -(u - c) K g / |g|^2 with
// g = K^T grad_xi u the world gradient (the plain reference-space step
// grad_xi u / |grad_xi u|^2 drifts sideways in world space wherever J is not
// conformal, and walks particles out through the channel walls). Whenever
// xi leaves the element's reference domain (after a move or a Newton step),
// the point continues in the neighbour element through the face it left by
// (ReferenceField::cross_face, world-exact for straight-sided elements and
// for the C1 B-spline map of the teardrop); a point
// that leaves through a boundary face is clamped onto that face (xi closest
// in the reference element) and Newton goes on from there within that
// face's plane (the minimum-norm correction tangent to the face, used when
// the free one points out of the mesh), so particles slide along the curve
// where the isosurface meets the mesh boundary instead of sticking. The
// field is only C0 across element faces: where a Newton step crosses a face
// and the residual does not shrink below 1/4 (Newton zig-zagging over a
// kink, linear convergence), the point goes back to where the step crossed
// the face and Newton goes on within that face's plane, the same way.
//
// Pair energies are computed from world positions, so the packing is
// uniform on the world surface however the elements distort it.
#include <cstdint>
#include <string>
#include <vector>

#include "pm/field/hp_field.h"
#include "pm/field/reference_field.h"
#include "pm/sample/engine.h"

namespace pm {

class HpConstraint : public SurfaceRules {
 public:
  struct State {
    std::int32_t element = -1;  ///< element index of the ReferenceField (not the Nektar++ id)
    Vec3 xi;                    ///< reference coordinates, Nektar++'s [-1, 1]^3 conventions
    Mat3 K;                     ///< J^-1 at xi (pulls world moves back)
    double residual = 0;        ///< u(xi) - c of our evaluator
    double curvedness = 0;      ///< sqrt(k1^2 + k2^2), 1/world units (0 unless curvature was asked for)
  };
  using Point = SamplePoint<State>;

  /// eps: |u - c| at which Newton stops (field units; default 1e-12 suits
  /// fields of order one: the polynomial then sits at round-off).
  /// curvature: evaluate the world Hessian for curvedness().
  HpConstraint(const ReferenceField& field, double iso, bool curvature, double eps = 1e-12);

  /// Project reference point (elem, xi) onto u = c: up to `steps` Newton steps.
  bool place_reference(int elem, const Vec3& xi, int steps, Point& out, Probe& pr) const;
  /// World point x: located (starting the walk at like's element when it has
  /// one), then projected; a point outside the mesh starts from its preimage
  /// in like's element (clamped onto the boundary), and fails (left_domain)
  /// when like has no element.
  bool place(const Vec3& x, const Point& like, int steps, double max_step, Point& out, Probe& pr) const;
  /// World tangent step pulled back with K, then projected.
  bool move(const Point& from, const Vec3& step, int steps, double max_step, Point& out, Probe& pr) const;
  double curvedness(const Point& p) const { return p.s.curvedness; }

  const ReferenceField& field() const { return f_; }
  double iso() const { return iso_; }

 private:
  // Bring (elem, xi) into the element that holds it, crossing faces and
  // clamping onto boundary faces; false on non-finite xi or too many crossings.
  // *wall: the boundary face of the final elem that xi was clamped onto (or -1).
  bool settle(int& elem, Vec3& xi, int* wall = nullptr) const;
  bool project(int elem, Vec3 xi, int steps, Point& out, Probe& pr) const;
  bool accept(int elem, const Vec3& xi, const HpSample& s, Point& out, Probe& pr) const;

  const ReferenceField& f_;
  double iso_;
  bool curvature_;
  double eps_;
};

struct HpParticleParams {
  double iso = 0;          ///< isovalue c
  double spacing = 0;      ///< planar spacing s between particles, world units (> 0)
  double density = 0;      ///< curvature adaptivity rho (particles per radian), 0 = uniform
  double alpha_cap = 10;   ///< with density: local spacing never below s / alpha_cap
  double eps = 1e-12;      ///< Newton tolerance |u - c|, field units
  /// Seeds: crossings of u = c along the edges of an equispaced lattice in
  /// each element's reference space (tetrahedra: the simplex part), this
  /// many points per element edge; 0 = a step of about 2 s over the
  /// element's diameter (at least modes + 1, at most 64). Population control
  /// grows the seeds to the spacing.
  int seed_points = 0;
  double seed_thinning = 0.5;  ///< seeds closer than this × s to a kept seed are dropped (0 = keep all)
  /// Coarse-to-fine: converge at spacing s 2^k (k = floor(log2(coarse_start / s)), at most 8),
  /// split every particle into 4, halve, repeat down to s.
  bool coarse_to_fine = false;
  double coarse_start = 0;  ///< coarsest spacing, world units (0 = 4 × the field's resolution)
  ParticleEnergy energy = ParticleEnergy::cotangent;
  double tolerance = 0.0015;
  int max_iters = 2000;
  int population_interval = 50;
  double population_tolerance = 0.001;
  std::uint64_t seed = 1;
  bool progress = true;
  double settled_move = 0;
  int reproject_steps = 6;  ///< Newton steps after a tangent move
  double step_factor = engine_constants::kLambdaFactor;  ///< adaptive step factor (> 1), see EngineParams
  StepControl step_control = StepControl::factor;        ///< see StepControl
};

struct HpParticleResult {
  std::vector<Vec3> positions;   ///< #N world points T_e(xi), world units
  std::vector<Vec3> normals;     ///< #N unit world normals, towards increasing u
  std::vector<int> element;      ///< #N field.element_id() of each particle (Nektar++ element ids for HpField)
  std::vector<Vec3> xi;          ///< #N reference coordinates
  std::vector<double> residual;  ///< #N |u - c| of our evaluator at the particle
  std::vector<double> energy, spacing;  ///< #N particle energy, local spacing (world units)
  int iterations = 0;
  int levels = 1;  ///< coarse-to-fine levels run
  bool converged = false;
  std::size_t seeds = 0, thinned = 0, dropped_init = 0, splits = 0, deletions = 0;
  /// Forward evaluations of the element polynomials F* and of the maps T
  /// (the field's counters over the run, seeds included).
  std::uint64_t field_evaluations = 0, map_evaluations = 0;
  std::uint64_t seed_evaluations = 0;  ///< of which the seeding lattice
  double energy_final = 0, energy_ideal = 0, mean_neighbours = 0;
  EngineStats engine;
  double seconds = 0;
};

/// Particles on u = iso of `field`, uniform spacing (or curvature-adaptive
/// with density > 0) on the world surface.
/// \throw UsageError when spacing <= 0 or larger than the mesh's diagonal,
///   density < 0, alpha_cap < 1, eps <= 0, tolerance <= 0, max_iters < 1,
///   seed_points is 1 or negative, seed_thinning outside [0, 2);
///   InputError when iso is not strictly between the field's lowest and
///   highest lattice value (no isosurface), or no seed reaches u = iso.
HpParticleResult distribute_hp_particles(const ReferenceField& field, const HpParticleParams& params);

}  // namespace pm
