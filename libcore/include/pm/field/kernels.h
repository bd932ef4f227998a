#pragma once
// 4-tap cubic reconstruction kernels on unit-spaced samples (SPEC §1).
// For a sample position t in voxel units with integer part i = floor(t) and
// fraction u = t - i, the four taps are samples i-1, i, i+1, i+2 with weights
// w[0..3] = f(u+1), f(u), f(u-1), f(u-2).

namespace pm {

enum class KernelType {
  bspline,     ///< cubic B-spline: approximating, C2
  catmull_rom, ///< Catmull-Rom: interpolating, C1
};

/// Kernel value and derivatives at offset x (in samples), support [-2, 2].
double kernel_value(KernelType k, double x);
double kernel_d1(KernelType k, double x);
double kernel_d2(KernelType k, double x);

/// Weights of the four taps for fraction u in [0,1): value, first and second
/// derivative (per sample unit).
void kernel_weights(KernelType k, double u, double w[4], double d1[4], double d2[4]);

}  // namespace pm
