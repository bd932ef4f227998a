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

/// "bspline" or "catmull-rom".
const char* kernel_name(KernelType k);

/// kernel_weights with the kernel fixed at compile time, inline for hot loops
/// (VolumeField). Any output may be nullptr and is then not computed.
template <KernelType K>
inline void kernel_weights_fixed(double u, double* w, double* d1, double* d2) {
  const double u2 = u * u, u3 = u2 * u;
  if constexpr (K == KernelType::bspline) {
    if (w) {
      const double v = 1.0 - u;
      w[0] = v * v * v * (1.0 / 6.0);
      w[1] = 0.5 * u3 - u2 + 2.0 / 3.0;
      w[2] = -0.5 * u3 + 0.5 * u2 + 0.5 * u + 1.0 / 6.0;
      w[3] = u3 * (1.0 / 6.0);
    }
    if (d1) {
      const double v = 1.0 - u;
      d1[0] = -0.5 * v * v;
      d1[1] = 1.5 * u2 - 2.0 * u;
      d1[2] = -1.5 * u2 + u + 0.5;
      d1[3] = 0.5 * u2;
    }
    if (d2) {
      d2[0] = 1.0 - u;
      d2[1] = 3.0 * u - 2.0;
      d2[2] = 1.0 - 3.0 * u;
      d2[3] = u;
    }
  } else {
    if (w) {
      const double v = 1.0 - u;
      w[0] = -0.5 * u * v * v;
      w[1] = 0.5 * (3.0 * u3 - 5.0 * u2) + 1.0;
      w[2] = 0.5 * u * (1.0 + 4.0 * u - 3.0 * u2);
      w[3] = -0.5 * u2 * v;
    }
    if (d1) {
      d1[0] = -1.5 * u2 + 2.0 * u - 0.5;
      d1[1] = 4.5 * u2 - 5.0 * u;
      d1[2] = -4.5 * u2 + 4.0 * u + 0.5;
      d1[3] = 1.5 * u2 - u;
    }
    if (d2) {
      d2[0] = 2.0 - 3.0 * u;
      d2[1] = 9.0 * u - 5.0;
      d2[2] = 4.0 - 9.0 * u;
      d2[3] = 3.0 * u - 1.0;
    }
  }
}

}  // namespace pm
