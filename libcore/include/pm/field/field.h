#pragma once
// The scalar-field interface shared by analytic implicits and reconstructed
// volumes. Everything is in world units. Surfaces are level sets F = iso with
// F < iso inside by convention (distance fields: negative inside).
#include <string>

#include "pm/base/vec.h"

namespace pm {

class ScalarField {
 public:
  virtual ~ScalarField() = default;
  /// F(x).
  virtual double value(const Vec3& x) const = 0;
  /// F(x) and its world gradient.
  virtual double value_gradient(const Vec3& x, Vec3& grad) const = 0;
  /// F(x), gradient and (symmetric) Hessian.
  virtual double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const = 0;
  /// World box where the field is defined (outside it values are clamped /
  /// extrapolated and must not be relied on).
  virtual Box domain() const = 0;
  /// Smallest feature scale worth resolving, e.g. the voxel size (world units).
  virtual double resolution() const = 0;
  /// Short description for stats ("sphere r=1", "volume head.nrrd bspline").
  virtual std::string describe() const = 0;
};

/// Which side of F = iso is the material: true when it is F < iso (distance
/// fields), false when it is F > iso (masks, CT intensities). Decided by the
/// eight corners of the field's domain, which are taken to be outside: the
/// material is below iso when at least four corners are above it.
bool material_below_iso(const ScalarField& f, double iso);

}  // namespace pm
