#include "pm/sample/element_constraint.h"

#include <cmath>

#include "engine_impl.h"

namespace pm {

namespace {
constexpr double kEpsG = 1e-9;        // |G| on the set (reference units)
constexpr double kEpsInverse = 1e-12; // |φ(u) - x|² of the map inversion, relative to |x|² + 1
constexpr int kInverseSteps = 30;     // Newton steps inverting φ
constexpr double kFlatGradient2 = 1e-300;

bool in_unit_cube(const Vec3& u) {
  return u.x >= 0 && u.x <= 1 && u.y >= 0 && u.y <= 1 && u.z >= 0 && u.z <= 1;
}
}  // namespace

Vec3 TrilinearElements::world(std::size_t e, const Vec3& u, Mat3* jac) const {
  const std::array<Vec3, 8>& c = corners_[e];
  Vec3 x, du, dv, dw;
  for (int k = 0; k < 8; ++k) {
    const int i = k & 1, j = (k >> 1) & 1, l = (k >> 2) & 1;
    const double a = i ? u.x : 1 - u.x, b = j ? u.y : 1 - u.y, g = l ? u.z : 1 - u.z;
    const double sa = i ? 1 : -1, sb = j ? 1 : -1, sg = l ? 1 : -1;
    x += c[std::size_t(k)] * (a * b * g);
    du += c[std::size_t(k)] * (sa * b * g);
    dv += c[std::size_t(k)] * (a * sb * g);
    dw += c[std::size_t(k)] * (a * b * sg);
  }
  if (jac)
    for (int r = 0; r < 3; ++r) {
      jac->m[r][0] = du[r];
      jac->m[r][1] = dv[r];
      jac->m[r][2] = dw[r];
    }
  return x;
}

ElementConstraint::ElementConstraint(const ElementMap& map, const ScalarField& reference)
    : map_(map), g_(reference) {}

bool ElementConstraint::project(std::size_t e, Vec3 u, int steps, Point& out, Probe& pr) const {
  Vec3 g;
  ++pr.evaluations;
  double f = g_.value_gradient(u, g);
  for (int k = 0; k < steps; ++k) {
    if (!std::isfinite(f) || !is_finite(g)) return pr.fail(ProjectFailure::non_finite);
    const double gg = norm2(g);
    if (!(gg > kFlatGradient2)) return pr.fail(ProjectFailure::flat);
    u -= g * (f / gg);
    if (!is_finite(u) || !in_unit_cube(u)) return pr.fail(ProjectFailure::left_domain);
    ++pr.evaluations;
    f = g_.value_gradient(u, g);
    if (std::fabs(f) <= kEpsG) {
      out.s.element = std::int32_t(e);
      out.s.u = u;
      out.s.ref_grad = g;
      out.x = map_.world(e, u, &out.s.jacobian);
      // World normal: ∇_x G = J⁻ᵀ ∇_u G.
      const Vec3 n = transpose(inverse(out.s.jacobian)) * g;
      if (!(norm2(n) > 0) || !is_finite(n)) return pr.fail(ProjectFailure::flat);
      out.n = normalized(n);
      return true;
    }
  }
  return pr.fail(ProjectFailure::no_convergence);
}

bool ElementConstraint::place_reference(std::size_t e, const Vec3& u, int steps, Point& out, Probe& pr) const {
  if (e >= map_.size()) return pr.fail(ProjectFailure::left_domain);
  return project(e, u, steps, out, pr);
}

bool ElementConstraint::place(const Vec3& x, const Point& like, int steps, double, Point& out, Probe& pr) const {
  const std::size_t e = std::size_t(like.s.element);
  if (e >= map_.size()) return pr.fail(ProjectFailure::left_domain);
  Vec3 u = like.s.u;
  const double tol = kEpsInverse * (norm2(x) + 1);
  bool found = false;
  for (int k = 0; k < kInverseSteps && !found; ++k) {
    Mat3 j;
    const Vec3 r = map_.world(e, u, &j) - x;
    if (norm2(r) <= tol) {
      found = true;
      break;
    }
    u -= inverse(j) * r;
    if (!is_finite(u)) return pr.fail(ProjectFailure::non_finite);
  }
  if (!found || !in_unit_cube(u)) return pr.fail(found ? ProjectFailure::left_domain : ProjectFailure::no_convergence);
  return project(e, u, steps, out, pr);
}

bool ElementConstraint::move(const Point& from, const Vec3& step, int steps, double, Point& out, Probe& pr) const {
  const Vec3 du = inverse(from.s.jacobian) * step;
  return project(std::size_t(from.s.element), from.s.u + du, steps, out, pr);
}

template class ParticleEngine<ElementConstraint>;

}  // namespace pm
