#pragma once
// A continuous field reconstructed from a volume by separable convolution
// with 4-tap kernels (SPEC §1), honouring the volume's geometry (origin,
// spacing and direction matrix). Samples outside the grid are clamped to the
// border (replicate).
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "pm/base/volume.h"
#include "pm/field/field.h"
#include "pm/field/kernels.h"

namespace pm {

struct VolumeFieldParams {
  KernelType value_kernel = KernelType::bspline;  ///< kernel for F
  KernelType deriv_kernel = KernelType::bspline;  ///< kernel for gradient and Hessian
  /// Use the AVX2 code path when the CPU has it (checked at run time; the
  /// results are bit-identical to the baseline x86-64 path, which false
  /// forces, e.g. to compare the two).
  bool allow_avx2 = true;
  /// Batch calls with at least this many points (n >= 2) evaluate them in
  /// the memory order of their voxel bricks and write each result to the
  /// caller's position: bit-identical, faster at random points in a volume
  /// larger than the caches once a batch is dense enough. The radix sort
  /// works on up to 2^20 points at a time in per-thread scratch of 68 bytes
  /// per point (140 with Hessians), kept for reuse (std::bad_alloc if it
  /// cannot grow). 0 (default): automatic, sorted when the voxels take more
  /// than 32 MiB and the batch has at least one point per four bricks (a
  /// brick is 4x2x2 voxels; 262144 points for 256³), where it measured
  /// faster (tests/bench/bench_field.cpp), unless the points already come
  /// in a coherent order (consecutive points mostly within two voxels of
  /// each other, judged on 64 pairs). SIZE_MAX: never.
  std::size_t sort_min_batch = 0;
  /// Chapter-5 mix: value from Catmull-Rom, derivatives from the B-spline.
  static VolumeFieldParams chapter5_mix() { return {KernelType::catmull_rom, KernelType::bspline}; }
};

/// World position x maps to index space by t = D⁻¹ (x - origin); gradient and
/// Hessian are converted back: ∇_world = D⁻ᵀ ∇_t, H_world = D⁻ᵀ H_t D⁻¹.
/// With mixed kernels the gradient and Hessian are those of the
/// deriv_kernel reconstruction (not the derivatives of value()). A NaN
/// position gives NaN results. Thread-safe for concurrent evaluation; no
/// allocation after construction, except the per-thread scratch of batches
/// evaluated in brick order (sort_min_batch). The batch calls prefetch a few
/// points ahead: at random points in a volume much larger than the caches
/// they are faster than single-point calls, and large batches evaluated in
/// brick order faster still (tests/bench/bench_field.cpp).
class VolumeField : public ScalarField {
 public:
  /// Copies the voxels as float (`name` is used in messages and describe()).
  /// \throw InputError on an empty volume, a singular direction matrix, or
  /// NaN/Inf voxels (or values beyond the float range), naming `name`, the
  /// first bad voxel and how many there are.
  explicit VolumeField(const Volume& v, VolumeFieldParams p = {}, std::string name = {});
  double value(const Vec3& x) const override;
  double value_gradient(const Vec3& x, Vec3& grad) const override;
  double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const override;
  void value_batch(const Vec3* x, std::size_t n, double* f) const override;
  void value_gradient_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad) const override;
  void evaluate_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) const override;
  /// World bounding box of the voxel nodes.
  Box domain() const override;
  /// Smallest voxel spacing (world units).
  double resolution() const override;
  std::string describe() const override;
  /// Per block: the least-squares linear fit L of the block's samples (the
  /// (block+3)³ nodes its cells' kernels read) and the largest residual e;
  /// both kernels reproduce linear functions, so |F - L| <= Σ|w| e, with
  /// Σ|w| <= 1 (B-spline) or 1.25³ (Catmull-Rom, whose negative weights
  /// sum to u(1-u)/2 <= 1/8 per axis). TBB over slabs of blocks.
  /// \pre block >= 1.
  std::shared_ptr<const ValueBounds> value_bounds(int block) const override;
  const Dims& dims() const { return dims_; }
  const Geometry& geometry() const { return geom_; }
  /// The kernel of value() (Catmull-Rom interpolates: value() at a node is
  /// that node's sample, up to the rounding of the world-to-index map).
  KernelType value_kernel() const { return params_.value_kernel; }
  /// The stored sample of node (i, j, k) (as float). \pre inside dims().
  float node_sample(std::size_t i, std::size_t j, std::size_t k) const {
    return data_[base_ + std::size_t(offset_[0][i + 3] + offset_[1][j + 3] + offset_[2][k + 3])];
  }
  /// True when evaluation runs the AVX2 code path.
  bool uses_avx2() const { return avx2_; }
  /// True when a batch call with n points evaluates them in brick order
  /// (VolumeFieldParams::sort_min_batch; with the automatic threshold, only
  /// if the points are not in a coherent order already).
  bool sorts_batch(std::size_t n) const { return n >= 2 && n >= sort_min_; }

 private:
  Dims dims_;
  Geometry geom_;
  Mat3 inv_dirs_;  // world -> index
  VolumeFieldParams params_;
  bool avx2_ = false;
  std::size_t sort_min_ = 0;  // batches from this size on run in brick order
  int key_bits_ = 0;          // bits of the largest brick index
  std::size_t bricks_ = 0;    // bricks in the storage
  std::vector<float> data_;
  std::string name_;
  // Voxel storage is bricked (see volume_field.cpp): voxel (i,j,k) lives at
  // data_[base_ + offset_[0][i+3] + offset_[1][j+3] + offset_[2][k+3]]; the
  // tables cover indices -3 .. n+3 with clamping to the border built in.
  // base_ aligns bricks to cache lines; a copy stays correct (offsets are
  // relative) but may lose that alignment.
  std::size_t base_ = 0;
  std::vector<std::ptrdiff_t> offset_[3];
};

}  // namespace pm
