#include "pm/field/curvature.h"

#include <cmath>

namespace pm {

double Curvature::curvedness() const { return std::sqrt(k1 * k1 + k2 * k2); }

Curvature curvature(const Vec3& grad, const Mat3& hess) {
  Curvature c;
  const double glen = norm(grad);
  if (!(glen > 0) || !std::isfinite(glen)) return c;
  const Vec3 n = grad / glen;
  c.normal = n;

  // G = P H P / |∇F| with P = I - n nᵀ (H symmetrised first), expressed in
  // an orthonormal tangent basis (t1, t2 = n x t1) as B = [[a, b], [b, d]]:
  // G = [t1 t2] B [t1 t2]ᵀ, so T = trace(G) = a + d and
  // 2N² - T² = 2(a² + 2b² + d²) - (a + d)² = (a - d)² + 4b². The closed
  // form κ1,2 = (T ± sqrt(2N² - T²))/2 is evaluated through the right-hand
  // side, which has no cancellation at umbilics (a sphere gives 1/R to
  // rounding, where 2N² - T² would leave sqrt(ε)/R of noise).
  const Vec3 helper = std::fabs(n.x) <= std::fabs(n.y) && std::fabs(n.x) <= std::fabs(n.z)
                          ? Vec3(1, 0, 0)
                          : (std::fabs(n.y) <= std::fabs(n.z) ? Vec3(0, 1, 0) : Vec3(0, 0, 1));
  const Vec3 t1 = normalized(cross(n, helper));
  const Vec3 t2 = cross(n, t1);
  // P t = t for tangent t, so tᵢᵀ G tⱼ = tᵢᵀ H tⱼ / |∇F|.
  const Mat3 H = (hess + transpose(hess)) * 0.5;
  const Vec3 Ht1 = H * t1, Ht2 = H * t2;
  const double a = dot(t1, Ht1) / glen, b = dot(t1, Ht2) / glen, d = dot(t2, Ht2) / glen;
  const double T = a + d;
  const double disc = std::sqrt((a - d) * (a - d) + 4.0 * b * b);
  c.k1 = 0.5 * (T + disc);
  c.k2 = 0.5 * (T - disc);

  // Principal directions: eigenvectors of B. atan2(0, 0) = 0 makes the
  // umbilic case (k1 = k2) return t1, t2.
  const double theta = 0.5 * std::atan2(2.0 * b, a - d);
  const double cs = std::cos(theta), sn = std::sin(theta);
  c.dir1 = cs * t1 + sn * t2;
  c.dir2 = cs * t2 - sn * t1;  // = n x dir1
  return c;
}

}  // namespace pm
