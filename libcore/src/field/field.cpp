#include "pm/field/field.h"

namespace pm {

void ScalarField::value_batch(const Vec3* x, std::size_t n, double* f) const {
  for (std::size_t k = 0; k < n; ++k) f[k] = value(x[k]);
}

void ScalarField::value_gradient_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad) const {
  for (std::size_t k = 0; k < n; ++k) f[k] = value_gradient(x[k], grad[k]);
}

void ScalarField::evaluate_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) const {
  for (std::size_t k = 0; k < n; ++k) f[k] = evaluate(x[k], grad[k], hess[k]);
}

bool material_below_iso(const ScalarField& f, double iso) {
  const Box d = f.domain();
  int above = 0;
  for (int c = 0; c < 8; ++c) {
    const Vec3 x((c & 1) ? d.hi.x : d.lo.x, (c & 2) ? d.hi.y : d.lo.y, (c & 4) ? d.hi.z : d.lo.z);
    above += f.value(x) > iso;
  }
  return above >= 4;
}

}  // namespace pm
