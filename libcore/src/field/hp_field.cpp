#include "pm/field/hp_field.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pm/base/error.h"

namespace pm {
namespace {

constexpr int kMaxModes = 20;  // as read_nektar_field allows

// ---- second-order jets: value, gradient and Hessian carried together ---------

// Three variables (xi1, xi2, xi3); h: xx yy zz xy xz yz.
struct Jet3 {
  double v = 0;
  double g[3] = {0, 0, 0};
  double h[6] = {0, 0, 0, 0, 0, 0};
  Jet3() = default;
  Jet3(double c) : v(c) {}  // NOLINT: constants convert implicitly
};
constexpr int kPi[6] = {0, 1, 2, 0, 0, 1};
constexpr int kPj[6] = {0, 1, 2, 1, 2, 2};

inline Jet3 operator+(Jet3 a, const Jet3& b) {
  a.v += b.v;
  for (int i = 0; i < 3; ++i) a.g[i] += b.g[i];
  for (int k = 0; k < 6; ++k) a.h[k] += b.h[k];
  return a;
}
inline Jet3 operator-(Jet3 a, const Jet3& b) {
  a.v -= b.v;
  for (int i = 0; i < 3; ++i) a.g[i] -= b.g[i];
  for (int k = 0; k < 6; ++k) a.h[k] -= b.h[k];
  return a;
}
inline Jet3 operator*(double s, Jet3 a) {
  a.v *= s;
  for (double& x : a.g) x *= s;
  for (double& x : a.h) x *= s;
  return a;
}
inline Jet3 operator*(const Jet3& a, const Jet3& b) {
  Jet3 r;
  r.v = a.v * b.v;
  for (int i = 0; i < 3; ++i) r.g[i] = a.v * b.g[i] + b.v * a.g[i];
  for (int k = 0; k < 6; ++k)
    r.h[k] = a.v * b.h[k] + b.v * a.h[k] + a.g[kPi[k]] * b.g[kPj[k]] + a.g[kPj[k]] * b.g[kPi[k]];
  return r;
}
inline Jet3& operator+=(Jet3& a, const Jet3& b) { return a = a + b; }

// One variable.
struct Jet1 {
  double v = 0, d = 0, dd = 0;
  Jet1() = default;
  Jet1(double c) : v(c) {}  // NOLINT
  Jet1(double v_, double d_, double dd_) : v(v_), d(d_), dd(dd_) {}
};
inline Jet1 operator+(Jet1 a, const Jet1& b) { return {a.v + b.v, a.d + b.d, a.dd + b.dd}; }
inline Jet1 operator-(Jet1 a, const Jet1& b) { return {a.v - b.v, a.d - b.d, a.dd - b.dd}; }
inline Jet1 operator*(double s, Jet1 a) { return {s * a.v, s * a.d, s * a.dd}; }
inline Jet1 operator*(const Jet1& a, const Jet1& b) {
  return {a.v * b.v, a.v * b.d + a.d * b.v, a.v * b.dd + 2 * a.d * b.d + a.dd * b.v};
}
inline Jet1& operator+=(Jet1& a, const Jet1& b) { return a = a + b; }

// Homogeneous Jacobi polynomials H_n(x, y) = (x+y)^n P_n^{(a,b)}((y-x)/(x+y)),
// n = 0..count-1, by the three-term recurrence multiplied through by (x+y):
// no division, so exact at x + y = 0 as well.
template <class T>
void jacobi_h(int count, double a, double b, const T& x, const T& y, T* out) {
  if (count <= 0) return;
  const T s = x + y;
  const T w = y - x;
  out[0] = T(1.0);
  if (count == 1) return;
  out[1] = 0.5 * ((a + b + 2) * w + (a - b) * s);
  const T s2 = s * s;
  for (int n = 1; n + 1 < count; ++n) {
    const double c = 2 * n + a + b;
    const double a1 = 2 * (n + 1) * (n + a + b + 1) * c;
    const double a2 = (c + 1) * (a * a - b * b);
    const double a3 = c * (c + 1) * (c + 2);
    const double a4 = 2 * (n + a) * (n + b) * (c + 2);
    out[n + 1] = (1.0 / a1) * ((a2 * s + a3 * w) * out[n] - a4 * (s2 * out[n - 1]));
  }
}

// Tetrahedron expansion in the division-free form (see hp_field.h):
// lambda0 = -(1+xi1+xi2+xi3)/2, lambda1 = (1+xi1)/2, mu = (1+xi2)/2,
// nu = (1+xi3)/2; t = lambda0 + lambda1, s3 = t + mu = (1-xi3)/2.
//   A_0 = lambda0, A_1 = lambda1, A_p = lambda0 lambda1 H^{(1,1)}_{p-2}(lambda0, lambda1)
//   B_p0 = 1; B_0q = mu H^{(1,1)}_{q-2}(t, mu) (q >= 2); B_pq = mu H^{(2p-1,1)}_{q-1}(t, mu)
//   C_{k,0} = 1; C_{0,r} = nu H^{(1,1)}_{r-2}(s3, nu) (r >= 2); C_{k,r} = nu H^{(2k-1,1)}_{r-1}(s3, nu)
//   phi_pqr = A_p B_pq C_{p+q,r}, except phi_001 = nu and phi_01r = mu C_{1,r}.
template <class T>
T tet_sum(const std::array<int, 3>& n, const double* c, const T& l0, const T& l1, const T& mu, const T& nu) {
  const int P = n[0], Q = n[1], R = n[2];
  const T t = l0 + l1;
  const T s3 = t + mu;
  T A[kMaxModes], J[kMaxModes], Bq[kMaxModes], C[kMaxModes];
  A[0] = l0;
  if (P > 1) A[1] = l1;
  if (P > 2) {
    jacobi_h(P - 2, 1.0, 1.0, l0, l1, J);
    const T l01 = l0 * l1;
    for (int p = 2; p < P; ++p) A[p] = l01 * J[p - 2];
  }
  // C_{k,r} for r < nr.
  auto row = [&](int k, int nr) {
    C[0] = T(1.0);
    if (k == 0) {
      if (nr > 1) C[1] = nu;  // the top vertex (used as phi_001 itself)
      if (nr > 2) {
        jacobi_h(nr - 2, 1.0, 1.0, s3, nu, J);
        for (int r = 2; r < nr; ++r) C[r] = nu * J[r - 2];
      }
    } else if (nr > 1) {
      jacobi_h(nr - 1, 2.0 * k - 1, 1.0, s3, nu, J);
      for (int r = 1; r < nr; ++r) C[r] = nu * J[r - 1];
    }
  };
  T sum(0.0);
  int idx = 0;
  for (int p = 0; p < P; ++p) {
    const int nq = Q - p;
    if (nq <= 0) break;
    // B_pq for q < nq.
    Bq[0] = T(1.0);
    if (p == 0) {
      if (nq > 2) {
        jacobi_h(nq - 2, 1.0, 1.0, t, mu, J);
        for (int q = 2; q < nq; ++q) Bq[q] = mu * J[q - 2];
      }
    } else if (nq > 1) {
      jacobi_h(nq - 1, 2.0 * p - 1, 1.0, t, mu, J);
      for (int q = 1; q < nq; ++q) Bq[q] = mu * J[q - 1];
    }
    for (int q = 0; q < nq; ++q) {
      const int nr = R - p - q;
      if (nr <= 0) continue;
      row(p + q, nr);
      if (p == 0 && q == 1) {
        for (int r = 0; r < nr; ++r) sum += c[idx++] * (mu * C[r]);
        continue;
      }
      const T AB = p == 0 && q == 0 ? A[0] : A[p] * Bq[q];
      for (int r = 0; r < nr; ++r) {
        if (p == 0 && q == 0 && r == 1)
          sum += c[idx++] * nu;
        else
          sum += c[idx++] * (AB * C[r]);
      }
    }
  }
  return sum;
}

// Modified_A psi_0..psi_{n-1} of a jet argument z.
template <class T>
void modified_a_jet(int n, const T& x, const T& y, T* out) {  // x = (1-z)/2, y = (1+z)/2
  if (n > 0) out[0] = x;
  if (n > 1) out[1] = y;
  if (n > 2) {
    T J[kMaxModes];
    jacobi_h(n - 2, 1.0, 1.0, x, y, J);
    const T xy = x * y;
    for (int p = 2; p < n; ++p) out[p] = xy * J[p - 2];
  }
}

// 1D Modified_B psi_{pq}(z) (row p), plain doubles, for the collapsed reference.
double modified_b(int p, int q, double z) {
  const double x = 0.5 * (1 - z), y = 0.5 * (1 + z);
  double J[kMaxModes];
  if (p == 0) {
    if (q == 0) return x;
    if (q == 1) return y;
    jacobi_h(q - 1, 1.0, 1.0, x, y, J);
    return x * y * J[q - 2];
  }
  const double xp = std::pow(x, p);
  if (q == 0) return xp;
  jacobi_h(q, 2.0 * p - 1, 1.0, x, y, J);
  return xp * y * J[q - 1];
}

Jet3 lin(double c0, double g0, double g1, double g2) {
  Jet3 r(c0);
  r.g[0] = g0;
  r.g[1] = g1;
  r.g[2] = g2;
  return r;
}

Vec3 project_capped_simplex(Vec3 u) {
  // Closest point of {u >= 0, u0 + u1 + u2 <= 1}.
  Vec3 c{std::max(0.0, u.x), std::max(0.0, u.y), std::max(0.0, u.z)};
  if (c.x + c.y + c.z <= 1) return c;
  // Projection onto the probability simplex (sort-based).
  double s[3] = {u.x, u.y, u.z};
  std::sort(s, s + 3, [](double a, double b) { return a > b; });
  double cum = 0, theta = 0;
  for (int k = 0; k < 3; ++k) {
    cum += s[k];
    const double th = (cum - 1) / (k + 1);
    if (s[k] - th > 0) theta = th;
  }
  return {std::max(0.0, u.x - theta), std::max(0.0, u.y - theta), std::max(0.0, u.z - theta)};
}

}  // namespace

namespace hp {

void modified_a(int n, double z, double* v, double* d, double* dd) {
  Jet1 x, y, out[kMaxModes];
  x.v = 0.5 * (1 - z);
  x.d = -0.5;
  y.v = 0.5 * (1 + z);
  y.d = 0.5;
  modified_a_jet(n, x, y, out);
  for (int p = 0; p < n; ++p) {
    if (v) v[p] = out[p].v;
    if (d) d[p] = out[p].d;
    if (dd) dd[p] = out[p].dd;
  }
}

double tet_value_collapsed(const std::array<int, 3>& n, const double* c, const Vec3& xi) {
  // Nektar++'s LocCoordToLocCollapsed, with its clamp at the collapsed edge.
  const double tol = 1e-12;
  double d2 = 1 - xi.z, d12 = -xi.y - xi.z;
  if (std::fabs(d2) < tol) d2 = d2 >= 0 ? tol : -tol;
  if (std::fabs(d12) < tol) d12 = d12 >= 0 ? tol : -tol;
  const double e1 = 2 * (1 + xi.x) / d12 - 1, e2 = 2 * (1 + xi.y) / d2 - 1, e3 = xi.z;
  double a[kMaxModes];
  modified_a(n[0], e1, a, nullptr, nullptr);
  double u = 0, top = 0, col01 = 0;
  int idx = 0;
  for (int p = 0; p < n[0]; ++p)
    for (int q = 0; q < n[1] - p; ++q)
      for (int r = 0; r < n[2] - p - q; ++r) {
        const double cc = c[idx++];
        const double b = modified_b(p, q, e2), cz = modified_b(p + q, r, e3);
        u += cc * a[p] * b * cz;
        if (p == 0 && q == 0 && r == 1) top = cc * cz;  // c_001 psiC_001
        if (p == 0 && q == 1) col01 += cc * cz;          // sum_r c_01r psiC_01r
      }
  // The split top vertex: (1+c)/2 (1+b)/2 (1-a)/2 and (1+c)/2 (1-b)/2 (1+a)/2,
  // then the (1+b)/2 (1+a)/2 part of the collapsed vertex and edge modes.
  u += top * (a[0] * modified_b(0, 1, e2) + a[1] * modified_b(1, 0, e2));
  u += a[1] * modified_b(0, 1, e2) * (col01 + top);
  return u;
}

double tet_evaluate(const std::array<int, 3>& n, const double* c, const Vec3& xi, Vec3* g, Mat3* H) {
  if (!g && !H) {
    const double l0 = -0.5 * (1 + xi.x + xi.y + xi.z), l1 = 0.5 * (1 + xi.x), mu = 0.5 * (1 + xi.y),
                 nu = 0.5 * (1 + xi.z);
    return tet_sum<double>(n, c, l0, l1, mu, nu);
  }
  const Jet3 l0 = lin(-0.5 * (1 + xi.x + xi.y + xi.z), -0.5, -0.5, -0.5);
  const Jet3 l1 = lin(0.5 * (1 + xi.x), 0.5, 0, 0);
  const Jet3 mu = lin(0.5 * (1 + xi.y), 0, 0.5, 0);
  const Jet3 nu = lin(0.5 * (1 + xi.z), 0, 0, 0.5);
  const Jet3 u = tet_sum<Jet3>(n, c, l0, l1, mu, nu);
  if (g) *g = {u.g[0], u.g[1], u.g[2]};
  if (H)
    for (int k = 0; k < 6; ++k) H->m[kPi[k]][kPj[k]] = H->m[kPj[k]][kPi[k]] = u.h[k];
  return u.v;
}

double hex_evaluate(const std::array<int, 3>& n, const double* c, const Vec3& xi, Vec3* g, Mat3* H) {
  double a[3][kMaxModes], da[3][kMaxModes], dda[3][kMaxModes];
  for (int k = 0; k < 3; ++k) modified_a(n[k], xi[k], a[k], da[k], dda[k]);
  double v = 0, g0 = 0, g1 = 0, g2 = 0, h00 = 0, h11 = 0, h22 = 0, h01 = 0, h02 = 0, h12 = 0;
  int idx = 0;
  const bool deriv = g || H;
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j) {
      // Sums over i of c * psi_i (and its derivatives) for this (j, k).
      double s = 0, sd = 0, sdd = 0;
      for (int i = 0; i < n[0]; ++i, ++idx) {
        s += c[idx] * a[0][i];
        if (deriv) {
          sd += c[idx] * da[0][i];
          sdd += c[idx] * dda[0][i];
        }
      }
      const double bj = a[1][j], ck = a[2][k];
      v += s * bj * ck;
      if (!deriv) continue;
      const double dbj = da[1][j], ddbj = dda[1][j], dck = da[2][k], ddck = dda[2][k];
      g0 += sd * bj * ck;
      g1 += s * dbj * ck;
      g2 += s * bj * dck;
      h00 += sdd * bj * ck;
      h11 += s * ddbj * ck;
      h22 += s * bj * ddck;
      h01 += sd * dbj * ck;
      h02 += sd * bj * dck;
      h12 += s * dbj * dck;
    }
  if (g) *g = {g0, g1, g2};
  if (H) {
    H->m[0][0] = h00;
    H->m[1][1] = h11;
    H->m[2][2] = h22;
    H->m[0][1] = H->m[1][0] = h01;
    H->m[0][2] = H->m[2][0] = h02;
    H->m[1][2] = H->m[2][1] = h12;
  }
  return v;
}

}  // namespace hp

// ---- HpField --------------------------------------------------------------------

namespace {
constexpr int kTetFaceVerts[4][3] = {{0, 1, 2}, {0, 1, 3}, {1, 2, 3}, {0, 2, 3}};
const Vec3 kHexRef[8] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                         {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
}  // namespace

HpField::HpField(const NektarMesh& mesh, const NektarField& field, const std::string& variable, HpFieldParams params)
    : params_(params) {
  const int var = field.variable(variable);
  check_field_matches_mesh(field, mesh);
  const std::string where = "HpField: " + quote(mesh.path) + " + " + quote(field.path);
  elems_.resize(mesh.elements.size());
  double min_edge = std::numeric_limits<double>::infinity();
  int max_modes = 2;
  for (std::size_t i = 0; i < mesh.elements.size(); ++i) {
    const NektarElement& me = mesh.elements[i];
    std::string curved;
    if (mesh.element_curved(me, &curved))
      throw InputError(where + ": element " + std::to_string(me.id) + " (" + nektar_shape_name(me.shape) +
                       ") has curved " + curved + "; curved elements are not supported yet");
    auto it = field.element_index.find(me.id);
    if (it == field.element_index.end())
      throw InputError(where + ": mesh element " + std::to_string(me.id) + " has no coefficients in the field");
    const NektarFieldElement& fe = field.elements[it->second];
    Elem& e = elems_[i];
    e.id = me.id;
    e.shape = me.shape;
    e.modes = fe.modes;
    e.coeffs.assign(fe.coeffs.begin() + static_cast<std::ptrdiff_t>(var) * fe.ncoeffs,
                    fe.coeffs.begin() + static_cast<std::ptrdiff_t>(var + 1) * fe.ncoeffs);
    for (int k = 0; k < me.nverts; ++k) {
      e.v[k] = mesh.vertex(me.verts[k]);
      e.box.extend(e.v[k]);
      box_.extend(e.v[k]);
    }
    for (int a = 0; a < me.nverts; ++a)
      for (int b = a + 1; b < me.nverts; ++b) {
        const double d = norm(e.v[a] - e.v[b]);
        if (d > 0) min_edge = std::min(min_edge, d);
      }
    max_modes = std::max({max_modes, fe.modes[0], fe.modes[1], fe.modes[2]});
    e.nb.fill(-1);
    e.nb_face.fill(-1);
    if (e.shape == NektarShape::Tetrahedron) {
      e.J = Mat3::from_columns(0.5 * (e.v[1] - e.v[0]), 0.5 * (e.v[2] - e.v[0]), 0.5 * (e.v[3] - e.v[0]));
      const double det = determinant(e.J);
      const double scale = norm(e.v[1] - e.v[0]) * norm(e.v[2] - e.v[0]) * norm(e.v[3] - e.v[0]);
      if (!(std::fabs(det) > 1e-12 * scale / 8))
        throw InputError(where + ": tetrahedron " + std::to_string(e.id) + " is degenerate (Jacobian determinant " +
                         format_number(det) + ")");
      e.K = inverse(e.J);
    } else {
      // Check the trilinear map at the corners and the centre.
      for (int k = 0; k <= 8; ++k) {
        const Vec3 xi = k < 8 ? kHexRef[k] : Vec3{0, 0, 0};
        const double det = determinant(jacobian_nocount(e, xi));
        const double sz = norm(e.box.size());
        if (!(std::fabs(det) > 1e-12 * sz * sz * sz))
          throw InputError(where + ": hexahedron " + std::to_string(e.id) +
                           " is degenerate or inverted (Jacobian determinant " + format_number(det) + " at xi = (" +
                           format_number(xi.x) + ", " + format_number(xi.y) + ", " + format_number(xi.z) + "))");
      }
    }
    id_to_index_[e.id] = static_cast<int>(i);
  }
  // Adjacency through shared faces.
  std::unordered_map<int, std::pair<int, int>> first;  // face id -> (elem, local face)
  for (std::size_t i = 0; i < mesh.elements.size(); ++i) {
    const NektarElement& me = mesh.elements[i];
    for (int f = 0; f < me.nfaces; ++f) {
      auto [it, fresh] = first.emplace(me.faces[f], std::make_pair(static_cast<int>(i), f));
      if (fresh) continue;
      const int j = it->second.first, g = it->second.second;
      if (elems_[j].nb[g] >= 0)
        throw InputError(where + ": face " + std::to_string(me.faces[f]) + " is shared by more than two elements");
      elems_[i].nb[f] = j;
      elems_[i].nb_face[f] = g;
      elems_[j].nb[g] = static_cast<int>(i);
      elems_[j].nb_face[g] = f;
    }
  }
  resolution_ = min_edge / (max_modes - 1);
  description_ = "nektar " + mesh.path + ":" + variable + " (" + std::to_string(elems_.size()) + " elements, up to " +
                 std::to_string(max_modes) + " modes)";
  // Location grid.
  const int n = std::max(1, std::min(64, static_cast<int>(std::cbrt(static_cast<double>(elems_.size())) + 1)));
  grid_n_ = {n, n, n};
  const Vec3 size = box_.size();
  const double pad = 1e-9 * std::max({size.x, size.y, size.z, 1e-300});
  grid_lo_ = box_.lo - Vec3{pad, pad, pad};
  grid_cell_ = (size + Vec3{2 * pad, 2 * pad, 2 * pad}) / static_cast<double>(n);
  std::vector<std::vector<int>> cells(static_cast<std::size_t>(n) * n * n);
  auto cell_of = [&](double v, int a) {
    return std::clamp(static_cast<int>(std::floor((v - grid_lo_[a]) / grid_cell_[a])), 0, n - 1);
  };
  for (std::size_t i = 0; i < elems_.size(); ++i) {
    const Box& b = elems_[i].box;
    const int x0 = cell_of(b.lo.x - pad, 0), x1 = cell_of(b.hi.x + pad, 0);
    const int y0 = cell_of(b.lo.y - pad, 1), y1 = cell_of(b.hi.y + pad, 1);
    const int z0 = cell_of(b.lo.z - pad, 2), z1 = cell_of(b.hi.z + pad, 2);
    for (int z = z0; z <= z1; ++z)
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) cells[(static_cast<std::size_t>(z) * n + y) * n + x].push_back(static_cast<int>(i));
  }
  grid_start_.assign(cells.size() + 1, 0);
  for (std::size_t c = 0; c < cells.size(); ++c) grid_start_[c + 1] = grid_start_[c] + static_cast<int>(cells[c].size());
  grid_elems_.reserve(grid_start_.back());
  for (const auto& c : cells) grid_elems_.insert(grid_elems_.end(), c.begin(), c.end());
}

int HpField::element_index(int id) const {
  auto it = id_to_index_.find(id);
  return it == id_to_index_.end() ? -1 : it->second;
}

std::vector<Vec3> HpField::element_vertices(int elem) const {
  const Elem& e = elems_[elem];
  return {e.v.begin(), e.v.begin() + (e.shape == NektarShape::Tetrahedron ? 4 : 8)};
}

int HpField::neighbour(int elem, int face, int* nb_face) const {
  const Elem& e = elems_[elem];
  if (nb_face) *nb_face = e.nb_face[face];
  return e.nb[face];
}

Vec3 HpField::position_nocount(const Elem& e, const Vec3& xi) const {
  if (e.shape == NektarShape::Tetrahedron) return e.v[0] + e.J * (xi + Vec3{1, 1, 1});
  Vec3 x;
  for (int k = 0; k < 8; ++k) {
    const double w = 0.125 * (1 + kHexRef[k].x * xi.x) * (1 + kHexRef[k].y * xi.y) * (1 + kHexRef[k].z * xi.z);
    x += w * e.v[k];
  }
  return x;
}

Mat3 HpField::jacobian_nocount(const Elem& e, const Vec3& xi) const {
  if (e.shape == NektarShape::Tetrahedron) return e.J;
  Vec3 c[3];
  for (int k = 0; k < 8; ++k) {
    const Vec3& r = kHexRef[k];
    const double fx = 1 + r.x * xi.x, fy = 1 + r.y * xi.y, fz = 1 + r.z * xi.z;
    c[0] += (0.125 * r.x * fy * fz) * e.v[k];
    c[1] += (0.125 * fx * r.y * fz) * e.v[k];
    c[2] += (0.125 * fx * fy * r.z) * e.v[k];
  }
  return Mat3::from_columns(c[0], c[1], c[2]);
}

double HpField::eval_nocount(const Elem& e, const Vec3& xi, Vec3* g, Mat3* H) const {
  return e.shape == NektarShape::Tetrahedron ? hp::tet_evaluate(e.modes, e.coeffs.data(), xi, g, H)
                                             : hp::hex_evaluate(e.modes, e.coeffs.data(), xi, g, H);
}

Vec3 HpField::position(int elem, const Vec3& xi) const {
  nmap_.fetch_add(1, std::memory_order_relaxed);
  return position_nocount(elems_[elem], xi);
}

Mat3 HpField::jacobian(int elem, const Vec3& xi) const {
  nmap_.fetch_add(1, std::memory_order_relaxed);
  return jacobian_nocount(elems_[elem], xi);
}

void HpField::map_hessians(int elem, const Vec3& xi, Mat3 d2T[3]) const {
  const Elem& e = elems_[elem];
  for (int a = 0; a < 3; ++a) d2T[a] = Mat3{};
  if (e.shape == NektarShape::Tetrahedron) return;
  // Trilinear: only the mixed second derivatives are non-zero.
  for (int k = 0; k < 8; ++k) {
    const Vec3& r = kHexRef[k];
    const double fx = 1 + r.x * xi.x, fy = 1 + r.y * xi.y, fz = 1 + r.z * xi.z;
    const double w01 = 0.125 * r.x * r.y * fz, w02 = 0.125 * r.x * fy * r.z, w12 = 0.125 * fx * r.y * r.z;
    for (int a = 0; a < 3; ++a) {
      d2T[a].m[0][1] += w01 * e.v[k][a];
      d2T[a].m[0][2] += w02 * e.v[k][a];
      d2T[a].m[1][2] += w12 * e.v[k][a];
    }
  }
  for (int a = 0; a < 3; ++a) {
    d2T[a].m[1][0] = d2T[a].m[0][1];
    d2T[a].m[2][0] = d2T[a].m[0][2];
    d2T[a].m[2][1] = d2T[a].m[1][2];
  }
}

double HpField::ref_value(int elem, const Vec3& xi) const {
  nfield_.fetch_add(1, std::memory_order_relaxed);
  return eval_nocount(elems_[elem], xi, nullptr, nullptr);
}

double HpField::ref_evaluate(int elem, const Vec3& xi, Vec3& grad_ref, Mat3& hess_ref) const {
  nfield_.fetch_add(1, std::memory_order_relaxed);
  return eval_nocount(elems_[elem], xi, &grad_ref, &hess_ref);
}

HpSample HpField::sample(int elem, const Vec3& xi) const {
  const Elem& e = elems_[elem];
  nfield_.fetch_add(1, std::memory_order_relaxed);
  nmap_.fetch_add(1, std::memory_order_relaxed);
  HpSample s;
  s.x = position_nocount(e, xi);
  s.J = jacobian_nocount(e, xi);
  s.K = e.shape == NektarShape::Tetrahedron ? e.K : inverse(s.J);
  s.f = eval_nocount(e, xi, &s.grad_ref, &s.hess_ref);
  const Mat3 Kt = transpose(s.K);
  s.grad = Kt * s.grad_ref;
  Mat3 Hc = s.hess_ref;
  if (e.shape == NektarShape::Hexahedron) {
    Mat3 d2T[3];
    map_hessians(elem, xi, d2T);
    for (int a = 0; a < 3; ++a) Hc = Hc - d2T[a] * s.grad[a];
  }
  s.hess = Kt * Hc * s.K;
  return s;
}

bool HpField::contains(int elem, const Vec3& xi, double tol) const { return exit_face(elem, xi, tol) < 0; }

int HpField::exit_face(int elem, const Vec3& xi, double tol) const {
  double viol[6];
  int nf;
  if (elems_[elem].shape == NektarShape::Tetrahedron) {
    nf = 4;
    viol[0] = -1 - xi.z;
    viol[1] = -1 - xi.y;
    viol[2] = (xi.x + xi.y + xi.z + 1) / std::sqrt(3.0);
    viol[3] = -1 - xi.x;
  } else {
    nf = 6;
    viol[0] = -1 - xi.z;
    viol[1] = -1 - xi.y;
    viol[2] = xi.x - 1;
    viol[3] = xi.y - 1;
    viol[4] = -1 - xi.x;
    viol[5] = xi.z - 1;
  }
  int worst = -1;
  double w = tol;
  for (int f = 0; f < nf; ++f)
    if (viol[f] > w) {
      w = viol[f];
      worst = f;
    }
  if (!(std::isfinite(xi.x) && std::isfinite(xi.y) && std::isfinite(xi.z))) return 0;
  return worst;
}

Vec3 HpField::clamp_to_element(int elem, const Vec3& xi) const {
  if (elems_[elem].shape == NektarShape::Hexahedron)
    return {std::clamp(xi.x, -1.0, 1.0), std::clamp(xi.y, -1.0, 1.0), std::clamp(xi.z, -1.0, 1.0)};
  const Vec3 u = project_capped_simplex(0.5 * (xi + Vec3{1, 1, 1}));
  return 2.0 * u - Vec3{1, 1, 1};
}

bool HpField::inverse_map(int elem, const Vec3& x, Vec3& xi) const {
  const Elem& e = elems_[elem];
  if (e.shape == NektarShape::Tetrahedron) {
    nmap_.fetch_add(1, std::memory_order_relaxed);
    xi = e.K * (x - e.v[0]) - Vec3{1, 1, 1};
    return true;
  }
  // Newton on the trilinear map from the centre.
  xi = {0, 0, 0};
  const double scale = norm(e.box.size());
  for (int it = 0; it < params_.newton_iterations; ++it) {
    nmap_.fetch_add(2, std::memory_order_relaxed);
    const Vec3 r = position_nocount(e, xi) - x;
    const Mat3 J = jacobian_nocount(e, xi);
    const double det = determinant(J);
    if (!(std::fabs(det) > 0)) return false;
    const Vec3 d = inverse(J) * r;
    xi -= d;
    if (!is_finite(xi) || norm(xi) > 1e6) return false;
    if (norm(d) <= 4e-16 * std::max(1.0, norm(xi)) || norm(r) <= 1e-16 * scale) return true;
  }
  // Accept a converged-to-round-off iterate that stalled just above the test.
  const Vec3 r = position_nocount(e, xi) - x;
  return norm(r) <= 1e-12 * scale;
}

RefPoint HpField::locate_in_candidates(const Vec3& x, int hint) const {
  const double tol = params_.inside_tol;
  // Walk from the hint through the faces it exits by.
  if (hint >= 0 && hint < num_elements()) {
    int e = hint;
    for (int step = 0; step < 64 && e >= 0; ++step) {
      Vec3 xi;
      if (!inverse_map(e, x, xi)) break;
      const int f = exit_face(e, xi, tol);
      if (f < 0) return {e, xi};
      e = elems_[e].nb[f];
    }
  }
  const Vec3 rel = x - grid_lo_;
  int c[3];
  for (int a = 0; a < 3; ++a) {
    const double t = rel[a] / grid_cell_[a];
    if (!(t >= 0) || t > grid_n_[a]) return {};
    c[a] = std::min(grid_n_[a] - 1, static_cast<int>(t));
  }
  const std::size_t cell = (static_cast<std::size_t>(c[2]) * grid_n_[1] + c[1]) * grid_n_[0] + c[0];
  for (int k = grid_start_[cell]; k < grid_start_[cell + 1]; ++k) {
    const int e = grid_elems_[k];
    const Box& b = elems_[e].box;
    const double pad = 1e-9 * norm(b.size());
    if (x.x < b.lo.x - pad || x.x > b.hi.x + pad || x.y < b.lo.y - pad || x.y > b.hi.y + pad || x.z < b.lo.z - pad ||
        x.z > b.hi.z + pad)
      continue;
    Vec3 xi;
    if (inverse_map(e, x, xi) && contains(e, xi, tol)) return {e, xi};
  }
  return {};
}

RefPoint HpField::locate(const Vec3& x, int hint) const { return locate_in_candidates(x, hint); }

RefPoint HpField::nearest(const Vec3& x) const {
  // Outside every element: the element whose clamped preimage maps closest to x.
  RefPoint best;
  double bd = std::numeric_limits<double>::infinity();
  for (int e = 0; e < num_elements(); ++e) {
    const Box& b = elems_[e].box;
    double d2 = 0;
    for (int a = 0; a < 3; ++a) {
      const double d = std::max({b.lo[a] - x[a], 0.0, x[a] - b.hi[a]});
      d2 += d * d;
    }
    if (d2 >= bd * bd) continue;
    Vec3 xi;
    if (!inverse_map(e, x, xi)) xi = {0, 0, 0};
    xi = clamp_to_element(e, xi);
    const double d = norm(position_nocount(elems_[e], xi) - x);
    if (d < bd) {
      bd = d;
      best = {e, xi};
    }
  }
  return best;
}

RefPoint HpField::cross_face(int elem, int face, const Vec3& xi) const {
  const int nb = elems_[elem].nb[face];
  if (nb < 0) return {};
  const Vec3 x = position(elem, xi);
  Vec3 xn;
  if (!inverse_map(nb, x, xn)) return {};
  return {nb, xn};
}

double HpField::value(const Vec3& x) const {
  RefPoint p = locate(x);
  if (p.elem < 0) p = nearest(x);
  return ref_value(p.elem, p.xi);
}

double HpField::value_gradient(const Vec3& x, Vec3& grad) const {
  Mat3 H;
  return evaluate(x, grad, H);
}

double HpField::evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const {
  RefPoint p = locate(x);
  if (p.elem < 0) p = nearest(x);
  const HpSample s = sample(p.elem, p.xi);
  grad = s.grad;
  hess = s.hess;
  return s.f;
}

}  // namespace pm
