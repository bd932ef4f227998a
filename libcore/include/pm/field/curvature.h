#pragma once
// Principal curvatures from gradient and Hessian of an implicit (SPEC §1).
// Sign convention: for F < 0 inside, a sphere of radius R has κ1 = κ2 = 1/R.
#include "pm/base/vec.h"

namespace pm {

struct Curvature {
  double k1 = 0, k2 = 0;  ///< principal curvatures, k1 >= k2 (1/world units)
  Vec3 dir1, dir2;        ///< unit principal directions (tangent)
  Vec3 normal;            ///< unit normal ∇F/|∇F|
  double curvedness() const;  ///< C = sqrt(k1² + k2²)
  double mean() const { return 0.5 * (k1 + k2); }
  double gaussian() const { return k1 * k2; }
};

/// Precondition: |grad| > 0 (returns zeros otherwise).
Curvature curvature(const Vec3& grad, const Mat3& hess);

}  // namespace pm
