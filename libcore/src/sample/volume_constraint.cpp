#include "pm/sample/volume_constraint.h"

#include <cmath>

#include "engine_impl.h"

namespace pm {

namespace {
constexpr double kInsetPerResolution = 1e-3;  // placed points land this many resolutions inside
constexpr double kSpiralTurns = 1e3 * 0.6180339887498949;  // turns of the split-direction spiral (golden ratio)
}  // namespace

VolumeConstraint::VolumeConstraint(const ScalarField& field, double iso)
    : field_(field), iso_(iso), domain_(field.domain()) {}

bool VolumeConstraint::inside(const Vec3& x, Probe& pr) const {
  if (!is_finite(x) || !domain_.contains(x)) return pr.fail(ProjectFailure::left_domain);
  ++pr.evaluations;
  const double f = field_.value(x);
  if (!std::isfinite(f)) return pr.fail(ProjectFailure::non_finite);
  return f < iso_ ? true : pr.fail(ProjectFailure::left_domain);
}

bool VolumeConstraint::place(const Vec3& x0, const Point&, int steps, double max_step, Point& out,
                             Probe& pr) const {
  Probe first;
  if (inside(x0, first)) {
    pr.evaluations += first.evaluations;
    out.x = x0;
    out.n = Vec3{};
    return true;
  }
  pr.evaluations += first.evaluations;
  Vec3 x = x0;
  for (int k = 0; k < steps; ++k) {
    if (!is_finite(x) || !domain_.contains(x)) return pr.fail(ProjectFailure::left_domain);
    Vec3 g;
    ++pr.evaluations;
    const double f = field_.value_gradient(x, g);
    if (!std::isfinite(f) || !is_finite(g)) return pr.fail(ProjectFailure::non_finite);
    const double gg = norm2(g);
    if (!(gg > 0)) return pr.fail(ProjectFailure::flat);
    const double target = iso_ - kInsetPerResolution * field_.resolution() * std::sqrt(gg);
    if (f < iso_ && k > 0) break;
    Vec3 d = g * ((f - target) / gg);
    if (max_step > 0 && norm2(d) > max_step * max_step) d *= max_step / norm(d);
    x -= d;
  }
  if (!inside(x, pr)) return false;
  out.x = x;
  out.n = Vec3{};
  return true;
}

bool VolumeConstraint::move(const Point& from, const Vec3& step, int, double, Point& out, Probe& pr) const {
  const Vec3 x = from.x + step;
  if (!inside(x, pr)) return false;
  out.x = x;
  out.n = Vec3{};
  return true;
}

Vec3 VolumeConstraint::split_offset(const Point&, double u, double dist) const {
  const double z = 1 - 2 * u;
  const double r = std::sqrt(std::max(0.0, 1 - z * z));
  const double phi = 2 * engine_constants::kPi * (u * kSpiralTurns - std::floor(u * kSpiralTurns));
  return Vec3{r * std::cos(phi), r * std::sin(phi), z} * dist;
}

int VolumeConstraint::children(const Point&, double theta, double dist, Vec3* out) const {
  const double c = std::cos(theta), s = std::sin(theta);
  int k = 0;
  for (int dz = -1; dz <= 1; dz += 2)
    for (int dy = -1; dy <= 1; dy += 2)
      for (int dx = -1; dx <= 1; dx += 2)
        out[k++] = Vec3{c * dx - s * dy, s * dx + c * dy, double(dz)} * dist;
  return k;
}

template class ParticleEngine<VolumeConstraint>;

}  // namespace pm
