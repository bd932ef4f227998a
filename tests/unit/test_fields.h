#pragma once
// Analytic fields shared by the unit tests.
#include <string>

#include "pm/field/field.h"

namespace pm::test {

/// |x - c| - r: the exact distance to a sphere (so |∇| = 1), with its
/// Hessian; the domain is the cube of half-width `half` about c.
class Ball : public ScalarField {
 public:
  Ball(const Vec3& c, double r, double half) : c_(c), r_(r), half_(half) {}
  double value(const Vec3& x) const override { return norm(x - c_) - r_; }
  double value_gradient(const Vec3& x, Vec3& g) const override {
    g = normalized(x - c_);
    return norm(x - c_) - r_;
  }
  double evaluate(const Vec3& x, Vec3& g, Mat3& h) const override {
    const double d = norm(x - c_);
    g = (x - c_) / d;
    h = (Mat3::identity() - outer(g, g)) * (1.0 / d);
    return d - r_;
  }
  Box domain() const override {
    Box b;
    b.extend(c_ - Vec3{half_, half_, half_});
    b.extend(c_ + Vec3{half_, half_, half_});
    return b;
  }
  double resolution() const override { return r_ / 50; }
  std::string describe() const override { return "test ball"; }

 private:
  Vec3 c_;
  double r_, half_;
};

}  // namespace pm::test
