#include "pm/sample/surface_constraint.h"

#include <cmath>

#include "engine_impl.h"

namespace pm {

namespace {
constexpr double kEpsF = 1e-5;      // |F - iso| on the surface (SPEC §3)
constexpr double kFlatGradient2 = 1e-300;
}  // namespace

double curvedness_of(const Vec3& g, const Mat3& h) {
  const double gn = norm(g);
  if (!(gn > 0)) return 0;
  const Vec3 n = g / gn;
  const Mat3 p = Mat3::identity() - outer(n, n);
  const Mat3 php = p * h * p;
  double s = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) s += php.m[i][j] * php.m[i][j];
  return std::sqrt(s) / gn;
}

SurfaceConstraint::SurfaceConstraint(const ScalarField& field, double iso, bool curvature)
    : field_(field), iso_(iso), curvature_(curvature), domain_(field.domain()) {}

bool SurfaceConstraint::place(const Vec3& x0, const Point&, int steps, double max_step, Point& out,
                              Probe& pr) const {
  Vec3 x = x0, g;
  ++pr.evaluations;
  double f = field_.value_gradient(x, g) - iso_;
  if (!std::isfinite(f) || !is_finite(g)) return pr.fail(ProjectFailure::non_finite);
  for (int k = 0; k < steps; ++k) {
    const double gg = norm2(g);
    if (!(gg > kFlatGradient2)) return pr.fail(ProjectFailure::flat);
    Vec3 d = g * (f / gg);
    if (max_step > 0) {
      const double len2 = norm2(d);
      if (len2 > max_step * max_step) d *= max_step / std::sqrt(len2);
    }
    x -= d;
    if (!is_finite(x) || !domain_.contains(x)) return pr.fail(ProjectFailure::left_domain);
    ++pr.evaluations;
    f = field_.value_gradient(x, g) - iso_;
    if (!std::isfinite(f) || !is_finite(g)) return pr.fail(ProjectFailure::non_finite);
    if (std::fabs(f) <= kEpsF) {
      out.x = x;
      out.s.grad = g;
      out.n = normalized(g);
      out.s.curvedness = 0;
      if (curvature_) {
        Mat3 h;
        Vec3 g2;
        ++pr.evaluations;
        field_.evaluate(x, g2, h);
        out.s.curvedness = curvedness_of(g2, h);
      }
      return true;
    }
  }
  return pr.fail(ProjectFailure::no_convergence);
}

template class ParticleEngine<SurfaceConstraint>;

}  // namespace pm
