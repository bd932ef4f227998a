#pragma once
// Principal curvatures from gradient and Hessian of an implicit (SPEC §1).
// Sign convention: for F < 0 inside, a sphere of radius R has κ1 = κ2 = 1/R.
// Shape operator G = P H P / |∇F| with P = I - n nᵀ (SPEC §1 writes a minus
// sign, which belongs to the opposite inside convention); κ1,2 = (T ±
// sqrt(2N² - T²))/2 with T = trace(G), N = |G|_F, evaluated in a tangent
// basis where 2N² - T² = (a-d)² + 4b² for G's 2x2 block [[a,b],[b,d]] (no
// cancellation at umbilics). Saddles have κ2 < 0 (a torus's inner equator:
// κ2 = -1/(R-r)).
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

/// Curvature of the level set through a point with gradient `grad` and
/// Hessian `hess` (world units). When k1 = k2 the directions are an arbitrary
/// orthonormal tangent pair. dir1, dir2, normal form a right-handed frame.
/// Precondition: |grad| > 0 (returns all zeros otherwise).
Curvature curvature(const Vec3& grad, const Mat3& hess);

}  // namespace pm
