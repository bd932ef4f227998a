#pragma once
// The scalar-field interface shared by analytic implicits and reconstructed
// volumes. Everything is in world units. Surfaces are level sets F = iso with
// F < iso inside by convention (distance fields: negative inside).
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "pm/base/vec.h"

namespace pm {

/// Bounds of a field's value() over blocks of its voxel grid: for every x
/// whose voxel cell lies in a block, lo <= value(x) <= hi, guaranteed (not
/// estimated), so a caller can skip an evaluation whose outcome the bounds
/// already decide (e.g. the dominance check of a junction projection).
/// Made by ScalarField::value_bounds; thread-safe. A block's bounds are
/// computed when first asked for (most callers ask near a few surfaces
/// only): a pure function of the block, so any schedule gets the same ones.
/// Valid while the field that made them lives.
class ValueBounds {
 public:
  /// Computes block b's bounds (blocks x fastest).
  using Fill = std::function<void(std::size_t b, float& lo, float& hi)>;
  ValueBounds(std::size_t blocks, Fill fill);
  /// The bounds of the block holding x; false (lo, hi untouched) outside
  /// the grid's nodes or for a non-finite x.
  bool at(const Vec3& x, double& lo, double& hi) const;
  /// The same bounds negated (for -F); shares the computed blocks.
  ValueBounds negated() const;

  Mat3 to_index;       ///< world -> index: t = to_index (x - origin)
  Vec3 origin;
  int block = 4;       ///< voxel cells per block edge
  int n[3] = {0, 0, 0};   ///< grid nodes per axis
  int nb[3] = {0, 0, 0};  ///< blocks per axis

 private:
  struct Blocks;  // the fill and the computed blocks (lo, hi packed; unset until asked for)
  std::shared_ptr<Blocks> blocks_;
  bool negate_ = false;
};

class ScalarField {
 public:
  virtual ~ScalarField() = default;
  /// F(x).
  virtual double value(const Vec3& x) const = 0;
  /// F(x) and its world gradient.
  virtual double value_gradient(const Vec3& x, Vec3& grad) const = 0;
  /// F(x), gradient and (symmetric) Hessian.
  virtual double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const = 0;
  /// Batch forms of value, value_gradient and evaluate at the n points
  /// x[0..n): f[k], grad[k] and hess[k] (arrays of n) are bit for bit what
  /// the single-point call returns for x[k]. Outputs must not overlap x.
  /// The default loops over the single-point calls; VolumeField overlaps the
  /// memory accesses of consecutive points (worth it from a few dozen points
  /// on a volume larger than the caches).
  virtual void value_batch(const Vec3* x, std::size_t n, double* f) const;
  virtual void value_gradient_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad) const;
  virtual void evaluate_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) const;
  /// World box where the field is defined (outside it values are clamped /
  /// extrapolated and must not be relied on).
  virtual Box domain() const = 0;
  /// Smallest feature scale worth resolving, e.g. the voxel size (world units).
  virtual double resolution() const = 0;
  /// Short description for stats ("sphere r=1", "volume head.nrrd bspline").
  virtual std::string describe() const = 0;
  /// Guaranteed value bounds over blocks of `block` voxel cells, or null when
  /// the field cannot give them (analytic implicits). VolumeField computes
  /// them in one pass over its voxels.
  virtual std::shared_ptr<const ValueBounds> value_bounds(int block) const;
};

/// Which side of F = iso is the material: true when it is F < iso (distance
/// fields), false when it is F > iso (masks, CT intensities). Decided by the
/// eight corners of the field's domain, which are taken to be outside: the
/// material is below iso when at least four corners are above it.
bool material_below_iso(const ScalarField& f, double iso);

/// -F: turns a material above iso (masks, CT, indicators positive inside)
/// into one below -iso, the convention of the constraints. Either refers to
/// `f` (which must outlive it) or shares ownership of it.
class NegatedField final : public ScalarField {
 public:
  explicit NegatedField(const ScalarField& f) : f_(f) {}
  explicit NegatedField(std::shared_ptr<const ScalarField> f) : owned_(std::move(f)), f_(*owned_) {}
  double value(const Vec3& x) const override { return -f_.value(x); }
  double value_gradient(const Vec3& x, Vec3& grad) const override;
  double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const override;
  void value_batch(const Vec3* x, std::size_t n, double* f) const override;
  void value_gradient_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad) const override;
  void evaluate_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) const override;
  Box domain() const override { return f_.domain(); }
  double resolution() const override { return f_.resolution(); }
  std::string describe() const override { return "-(" + f_.describe() + ")"; }
  std::shared_ptr<const ValueBounds> value_bounds(int block) const override;

 private:
  std::shared_ptr<const ScalarField> owned_;
  const ScalarField& f_;
};

}  // namespace pm
