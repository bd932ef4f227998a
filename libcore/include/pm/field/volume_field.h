#pragma once
// A continuous field reconstructed from a volume by separable convolution
// with 4-tap kernels (SPEC §1), honouring the volume's geometry (origin,
// spacing and direction matrix). Samples outside the grid are clamped to the
// border (replicate).
#include <memory>
#include <vector>

#include "pm/base/volume.h"
#include "pm/field/field.h"
#include "pm/field/kernels.h"

namespace pm {

struct VolumeFieldParams {
  KernelType value_kernel = KernelType::bspline;  ///< kernel for F
  KernelType deriv_kernel = KernelType::bspline;  ///< kernel for gradient and Hessian
  /// Chapter-5 mix: value from Catmull-Rom, derivatives from the B-spline.
  static VolumeFieldParams chapter5_mix() { return {KernelType::catmull_rom, KernelType::bspline}; }
};

class VolumeField : public ScalarField {
 public:
  /// Copies the voxels as float. \throw InputError on NaN/Inf voxels.
  explicit VolumeField(const Volume& v, VolumeFieldParams p = {}, std::string name = {});
  double value(const Vec3& x) const override;
  double value_gradient(const Vec3& x, Vec3& grad) const override;
  double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const override;
  Box domain() const override;
  double resolution() const override;
  std::string describe() const override;
  const Dims& dims() const { return dims_; }
  const Geometry& geometry() const { return geom_; }

 private:
  Dims dims_;
  Geometry geom_;
  Mat3 inv_dirs_;  // world -> index
  VolumeFieldParams params_;
  std::vector<float> data_;
  std::string name_;
};

}  // namespace pm
