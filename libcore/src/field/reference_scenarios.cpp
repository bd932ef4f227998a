// TeardropField (a sphere in reference space under a quadratic B-spline map)
// and hex_power_field (x^k + y^k + z^k in one hexahedron): the built-in
// scenarios of Chapter 4.
#include "pm/field/reference_scenarios.h"

#include <algorithm>
#include <cmath>

#include "pm/base/error.h"

namespace pm {

namespace {
constexpr int kNewtonIterations = 50;
constexpr double kNewtonTol = 1e-14;  // |T(u) - x| / world size at which the inverse map stops
constexpr double kInsideTol = 1e-10;  // reference slack of locate

// Quadratic B-spline basis functions N_{s..s+2} on knot span s (t[s+2] <= u < t[s+3],
// knots t with 2 repeated end knots) at u, with first and second derivatives.
// The span is fixed, so outside it the span's polynomial is extrapolated.
void quadratic_basis(const std::vector<double>& t, int s, double u, double N[3], double dN[3], double ddN[3]) {
  const int i = s + 2;  // t[i] <= u < t[i+1]
  auto q = [](double a, double b) { return b == 0 ? 0.0 : a / b; };
  // Degree 1 on the span: N_{i-1,1}, N_{i,1}.
  const double a1 = q(t[i + 1] - u, t[i + 1] - t[i]), b1 = q(u - t[i], t[i + 1] - t[i]);
  const double da1 = q(-1, t[i + 1] - t[i]), db1 = -da1;
  // Degree 2: N_{i-2,2}, N_{i-1,2}, N_{i,2}.
  const double l0 = t[i + 1] - t[i - 1], l1 = t[i + 2] - t[i];
  N[0] = q(t[i + 1] - u, l0) * a1;
  N[1] = q(u - t[i - 1], l0) * a1 + q(t[i + 2] - u, l1) * b1;
  N[2] = q(u - t[i], l1) * b1;
  dN[0] = q(-2 * a1, l0);
  dN[1] = q(2 * a1, l0) - q(2 * b1, l1);
  dN[2] = q(2 * b1, l1);
  ddN[0] = q(-2 * da1, l0);
  ddN[1] = q(2 * da1, l0) - q(2 * db1, l1);
  ddN[2] = q(2 * db1, l1);
}
}  // namespace

TeardropField::TeardropField(TeardropParams p) : p_(p), n_(p.spans) {
  if (p.spans < 1 || p.spans > 64) throw UsageError("teardrop: spans must be in [1, 64], got " + std::to_string(p.spans));
  if (!(p.radius > 0) || !(p.radius < 0.5))
    throw UsageError("teardrop: radius must be in (0, 0.5) reference units, got " + format_number(p.radius));
  if (!(p.taper >= 0 && p.taper < 1)) throw UsageError("teardrop: taper must be in [0, 1), got " + format_number(p.taper));
  if (!(p.size > 0) || !(p.height > 0)) throw UsageError("teardrop: size and height must be > 0 world units");
  knots_ = {0, 0};
  for (int s = 0; s <= n_; ++s) knots_.push_back(double(s) / n_);
  knots_.push_back(1);
  knots_.push_back(1);
  const int m = n_ + 2;
  // Greville abscissae: with control points there the map is the identity
  // (linear precision); the net's width shrinks linearly with height.
  std::vector<double> g(m);
  for (int i = 0; i < m; ++i) g[i] = 0.5 * (knots_[i + 1] + knots_[i + 2]);
  ctrl_.resize(std::size_t(m) * m * m);
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        const double w = p.size * (1 - p.taper * g[k]);
        ctrl_[i + m * (j + m * std::size_t(k))] = {(g[i] - 0.5) * w, (g[j] - 0.5) * w, g[k] * p.height};
      }
  for (const Vec3& c : ctrl_) box_.extend(c);  // convex hull property
  resolution_ = std::min(p.size * (1 - p.taper), p.height) / n_ / 2;
}

Vec3 TeardropField::global(int elem, const Vec3& xi) const {
  const auto s = span_of(elem);
  const double h = 1.0 / n_;
  return {(s[0] + 0.5 * (xi.x + 1)) * h, (s[1] + 0.5 * (xi.y + 1)) * h, (s[2] + 0.5 * (xi.z + 1)) * h};
}

Vec3 TeardropField::eval_map(const std::array<int, 3>& s, const Vec3& u, Mat3* J, Mat3* d2T) const {
  double N[3][3], dN[3][3], ddN[3][3];
  for (int a = 0; a < 3; ++a) quadratic_basis(knots_, s[a], u[a], N[a], dN[a], ddN[a]);
  const int m = n_ + 2;
  Vec3 x;
  Mat3 Jm;
  Mat3 H[3];
  for (int c = 0; c < 3; ++c)
    for (int b = 0; b < 3; ++b)
      for (int a = 0; a < 3; ++a) {
        const Vec3& P = ctrl_[(s[0] + a) + m * ((s[1] + b) + m * std::size_t(s[2] + c))];
        x += P * (N[0][a] * N[1][b] * N[2][c]);
        if (J) {
          const double d[3] = {dN[0][a] * N[1][b] * N[2][c], N[0][a] * dN[1][b] * N[2][c], N[0][a] * N[1][b] * dN[2][c]};
          for (int r = 0; r < 3; ++r)
            for (int i = 0; i < 3; ++i) Jm.m[r][i] += P[r] * d[i];
        }
        if (d2T) {
          double h[3][3];
          const double* f[3] = {N[0], N[1], N[2]};
          const int idx[3] = {a, b, c};
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
              double v = 1;
              for (int ax = 0; ax < 3; ++ax) {
                const int order = (ax == i) + (ax == j);
                v *= order == 0 ? f[ax][idx[ax]] : order == 1 ? dN[ax][idx[ax]] : ddN[ax][idx[ax]];
              }
              h[i][j] = v;
            }
          for (int r = 0; r < 3; ++r)
            for (int i = 0; i < 3; ++i)
              for (int j = 0; j < 3; ++j) H[r].m[i][j] += P[r] * h[i][j];
        }
      }
  if (J) *J = Jm;
  if (d2T)
    for (int r = 0; r < 3; ++r) d2T[r] = H[r];
  return x;
}

Vec3 TeardropField::map(const Vec3& u) const {
  std::array<int, 3> s;
  for (int a = 0; a < 3; ++a) s[a] = std::clamp(int(std::floor(u[a] * n_)), 0, n_ - 1);
  return eval_map(s, u, nullptr, nullptr);
}

std::vector<Vec3> TeardropField::element_vertices(int elem) const {
  static const Vec3 ref[8] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                              {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
  std::vector<Vec3> v;
  for (const Vec3& r : ref) v.push_back(eval_map(span_of(elem), global(elem, r), nullptr, nullptr));
  return v;
}

double TeardropField::ref_value(int elem, const Vec3& xi) const {
  nfield_.fetch_add(1, std::memory_order_relaxed);
  return norm2(global(elem, xi) - p_.centre);
}

HpSample TeardropField::sample(int elem, const Vec3& xi) const {
  nfield_.fetch_add(1, std::memory_order_relaxed);
  nmap_.fetch_add(1, std::memory_order_relaxed);
  HpSample s;
  const Vec3 u = global(elem, xi);
  const double h = 0.5 / n_;  // du/dxi
  Mat3 Ju, d2u[3];
  s.x = eval_map(span_of(elem), u, &Ju, d2u);
  s.J = Ju * h;
  s.K = inverse(s.J);
  const Vec3 d = u - p_.centre;
  s.f = norm2(d);
  s.grad_ref = d * (2 * h);
  s.hess_ref = Mat3::diag(2 * h * h, 2 * h * h, 2 * h * h);
  s.grad = transpose(s.K) * s.grad_ref;
  Mat3 H = s.hess_ref;
  for (int a = 0; a < 3; ++a) H = H - d2u[a] * (s.grad[a] * h * h);
  s.hess = transpose(s.K) * H * s.K;
  return s;
}

int TeardropField::exit_face(int, const Vec3& xi, double tol) const {
  // Faces: 0 xi3=-1, 1 xi2=-1, 2 xi1=+1, 3 xi2=+1, 4 xi1=-1, 5 xi3=+1.
  const int face_of[3][2] = {{4, 2}, {1, 3}, {0, 5}};
  int best = -1;
  double worst = tol;
  for (int a = 0; a < 3; ++a) {
    if (-1 - xi[a] > worst) worst = -1 - xi[a], best = face_of[a][0];
    if (xi[a] - 1 > worst) worst = xi[a] - 1, best = face_of[a][1];
  }
  return best;
}

Vec3 TeardropField::clamp_to_element(int, const Vec3& xi) const {
  return {std::clamp(xi.x, -1.0, 1.0), std::clamp(xi.y, -1.0, 1.0), std::clamp(xi.z, -1.0, 1.0)};
}

RefPoint TeardropField::cross_face(int elem, int face, const Vec3& xi) const {
  static const int axis[6] = {2, 1, 0, 1, 0, 2}, dir[6] = {-1, -1, 1, 1, -1, 1};
  auto s = span_of(elem);
  s[axis[face]] += dir[face];
  if (s[axis[face]] < 0 || s[axis[face]] >= n_) return {};
  Vec3 x = xi;
  x[axis[face]] -= 2 * dir[face];  // the same u: one span further along
  return {elem_of(s), x};
}

bool TeardropField::inverse_map(int elem, const Vec3& x, Vec3& xi) const {
  const double scale = norm(box_.size());
  xi = {0, 0, 0};
  const double h = 0.5 / n_;
  for (int it = 0; it < kNewtonIterations; ++it) {
    nmap_.fetch_add(1, std::memory_order_relaxed);
    Mat3 Ju;
    const Vec3 r = eval_map(span_of(elem), global(elem, xi), &Ju, nullptr) - x;
    if (!is_finite(r)) return false;
    if (norm(r) <= kNewtonTol * scale) return true;
    const double det = determinant(Ju);
    if (!(std::fabs(det) > 0)) return false;
    xi -= inverse(Ju * h) * r;
  }
  return false;
}

RefPoint TeardropField::locate(const Vec3& x, int hint) const {
  // Newton in the hint's span, then walk: the span that holds the preimage.
  int elem = hint >= 0 && hint < num_elements() ? hint : elem_of({n_ / 2, n_ / 2, n_ / 2});
  for (int walk = 0; walk < 3 * n_ + 3; ++walk) {
    Vec3 xi;
    if (!inverse_map(elem, x, xi)) return {};
    const int f = exit_face(elem, xi, kInsideTol);
    if (f < 0) return {elem, clamp_to_element(elem, xi)};
    const RefPoint r = cross_face(elem, f, xi);
    if (r.elem < 0) return {};
    elem = r.elem;
  }
  return {};
}

std::string TeardropField::describe() const {
  return "teardrop (sphere |u - c| = " + format_number(p_.radius) + " in reference space, quadratic B-spline map, " +
         std::to_string(num_elements()) + " elements)";
}

// ---------------------------------------------------------------------------

HexPowerScenario hex_power_field(int k, const Vec3& lo, const Vec3& hi) {
  if (k < 1 || k > 12) throw UsageError("hex_power_field: order must be in [1, 12], got " + std::to_string(k));
  for (int a = 0; a < 3; ++a)
    if (!(hi[a] > lo[a])) throw UsageError("hex_power_field: expected lo < hi on every axis");
  const int P = k + 1;
  // 1-D Modified_A coefficients of t(z)^k, t = lo + (z + 1)/2 (hi - lo):
  // interpolation at the Chebyshev-Lobatto points (exact: t^k has degree k).
  auto coeffs_1d = [&](double l, double h) {
    std::vector<double> A(std::size_t(P) * P), b(P), v(P);
    for (int r = 0; r < P; ++r) {
      const double z = -std::cos(M_PI * r / k);
      hp::modified_a(P, z, v.data(), nullptr, nullptr);
      for (int c = 0; c < P; ++c) A[r * P + c] = v[c];
      b[r] = std::pow(l + 0.5 * (z + 1) * (h - l), k);
    }
    for (int c = 0; c < P; ++c) {  // Gaussian elimination, partial pivoting
      int piv = c;
      for (int r = c + 1; r < P; ++r)
        if (std::fabs(A[r * P + c]) > std::fabs(A[piv * P + c])) piv = r;
      for (int j = 0; j < P; ++j) std::swap(A[c * P + j], A[piv * P + j]);
      std::swap(b[c], b[piv]);
      for (int r = c + 1; r < P; ++r) {
        const double f = A[r * P + c] / A[c * P + c];
        for (int j = c; j < P; ++j) A[r * P + j] -= f * A[c * P + j];
        b[r] -= f * b[c];
      }
    }
    for (int c = P - 1; c >= 0; --c) {
      for (int j = c + 1; j < P; ++j) b[c] -= A[c * P + j] * b[j];
      b[c] /= A[c * P + c];
    }
    return b;
  };
  std::vector<double> one(P, 0.0);
  one[0] = one[1] = 1;  // psi_0 + psi_1 = 1
  const std::vector<double> cx = coeffs_1d(lo.x, hi.x), cy = coeffs_1d(lo.y, hi.y), cz = coeffs_1d(lo.z, hi.z);
  HexPowerScenario s;
  s.mesh.path = "hex_power_" + std::to_string(k);
  const Vec3 v[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z},
                     {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
  NektarElement e;
  e.id = 0;
  e.shape = NektarShape::Hexahedron;
  e.nverts = 8;
  e.nfaces = 6;
  for (int i = 0; i < 8; ++i) {
    s.mesh.vertices.push_back(v[i]);
    s.mesh.vertex_index[i] = i;
    e.verts[i] = i;
  }
  for (int f = 0; f < 6; ++f) e.faces[f] = f;
  for (int i = 0; i < 12; ++i) e.edges[i] = i;
  s.mesh.elements.push_back(e);
  s.mesh.element_index[0] = 0;
  s.mesh.expansion_modes = P;
  NektarFieldElement fe;
  fe.id = 0;
  fe.shape = NektarShape::Hexahedron;
  fe.modes = {P, P, P};
  fe.ncoeffs = P * P * P;
  fe.coeffs.resize(std::size_t(fe.ncoeffs));
  for (int c = 0; c < P; ++c)
    for (int b = 0; b < P; ++b)
      for (int a = 0; a < P; ++a)
        fe.coeffs[a + P * (b + P * std::size_t(c))] = cx[a] * one[b] * one[c] + one[a] * cy[b] * one[c] + one[a] * one[b] * cz[c];
  s.field.path = s.mesh.path + ".fld";
  s.field.names = {"u"};
  s.field.elements.push_back(fe);
  s.field.element_index[0] = 0;
  return s;
}

}  // namespace pm
