#pragma once
// Constraint of the particle engine (pm/sample/engine.h): an implicit
// surface F = iso (SPEC §3, Meyer 2008 Chapters 3 and 5). A particle carries
// ∇F at its point (the tangent projection uses it) and, when asked for, the
// curvedness sqrt(κ1² + κ2²) for curvature adaptivity. Newton projection
// x <- x - (F - iso) ∇F/|∇F|² until |F - iso| <= ε_F = 1e-5.
#include <cstdint>

#include "pm/field/field.h"
#include "pm/sample/engine.h"

namespace pm {

class SurfaceConstraint : public SurfaceRules {
 public:
  struct State {
    Vec3 grad;              ///< ∇F at the point, world units
    double curvedness = 0;  ///< 1/world units (0 unless curvature was asked for)
  };
  using Point = SamplePoint<State>;

  /// curvature: evaluate the Hessian at projected points for curvedness().
  SurfaceConstraint(const ScalarField& field, double iso, bool curvature);

  /// Newton from x, up to `steps` steps (at least one), each at most
  /// max_step long (0 = unlimited); fails on a non-finite field, a zero
  /// gradient, leaving the domain, or no convergence.
  bool place(const Vec3& x, const Point& like, int steps, double max_step, Point& out, Probe& pr) const;
  bool move(const Point& from, const Vec3& step, int steps, double max_step, Point& out, Probe& pr) const {
    return place(from.x + step, from, steps, max_step, out, pr);
  }
  /// (I - ∇F ∇Fᵀ/|∇F|²) v.
  Vec3 tangent(const Point& p, const Vec3& v) const {
    return v - p.s.grad * (dot(p.s.grad, v) / norm2(p.s.grad));
  }
  double curvedness(const Point& p) const { return p.s.curvedness; }

  const ScalarField& field() const { return field_; }
  double iso() const { return iso_; }

 private:
  const ScalarField& field_;
  double iso_;
  bool curvature_;
  Box domain_;
};

/// Curvedness sqrt(κ1² + κ2²) = ‖P H P‖_F / |∇F| from ∇F and the Hessian.
double curvedness_of(const Vec3& g, const Mat3& h);

}  // namespace pm
