#include "pm/field/kernels.h"

#include <cmath>

namespace pm {

// Piecewise forms in |x| (written independently of kernel_weights_fixed so
// the tests can cross-check the two).
//   B-spline:    |x|<1: (4 - 6x² + 3|x|³)/6        1<=|x|<2: (2-|x|)³/6
//   Catmull-Rom: |x|<1: 1 - 5x²/2 + 3|x|³/2        1<=|x|<2: 2 - 4|x| + 5x²/2 - |x|³/2
// The outer Catmull-Rom pieces are evaluated factored, -(|x|-1)(|x|-2)²/2 and
// -(3|x|-4)(|x|-2)/2, to avoid cancellation near |x| = 2.

double kernel_value(KernelType k, double x) {
  const double a = std::fabs(x);
  if (a >= 2.0) return 0.0;
  if (k == KernelType::bspline) {
    if (a < 1.0) return (4.0 - 6.0 * a * a + 3.0 * a * a * a) / 6.0;
    const double b = 2.0 - a;
    return b * b * b / 6.0;
  }
  if (a < 1.0) return 1.0 - 2.5 * a * a + 1.5 * a * a * a;
  return -0.5 * (a - 1.0) * (a - 2.0) * (a - 2.0);
}

double kernel_d1(KernelType k, double x) {
  const double a = std::fabs(x);
  if (a >= 2.0) return 0.0;
  const double s = x < 0 ? -1.0 : 1.0;
  if (k == KernelType::bspline) {
    if (a < 1.0) return s * (-2.0 * a + 1.5 * a * a);
    const double b = 2.0 - a;
    return s * (-0.5 * b * b);
  }
  if (a < 1.0) return s * (-5.0 * a + 4.5 * a * a);
  return s * (-0.5 * (3.0 * a - 4.0) * (a - 2.0));
}

double kernel_d2(KernelType k, double x) {
  const double a = std::fabs(x);
  if (a >= 2.0) return 0.0;
  if (k == KernelType::bspline) {
    if (a < 1.0) return -2.0 + 3.0 * a;
    return 2.0 - a;
  }
  if (a < 1.0) return -5.0 + 9.0 * a;
  return 5.0 - 3.0 * a;
}

void kernel_weights(KernelType k, double u, double w[4], double d1[4], double d2[4]) {
  if (k == KernelType::bspline)
    kernel_weights_fixed<KernelType::bspline>(u, w, d1, d2);
  else
    kernel_weights_fixed<KernelType::catmull_rom>(u, w, d1, d2);
}

const char* kernel_name(KernelType k) {
  return k == KernelType::bspline ? "bspline" : "catmull-rom";
}

}  // namespace pm
