#include "pm/field/junctions.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "pm/base/error.h"

namespace pm {

double smooth_max_spec(const double* z, std::size_t m, double eps) {
  double mx = z[0];
  for (std::size_t i = 1; i < m; ++i) mx = std::max(mx, z[i]);
  std::size_t k = 0;
  for (std::size_t i = 0; i < m; ++i) k += z[i] == mx ? 1 : 0;
  auto g = [eps](double d) { return 1.0 + d / std::sqrt(d * d + eps); };
  double sum = 0;
  for (std::size_t i = 0; i < m; ++i) {
    double w = 1;
    for (std::size_t j = 0; j < m; ++j)
      if (j != i) w *= g(z[i] - z[j]);
    sum += z[i] * w;
  }
  return sum / (double(k) * std::ldexp(1.0, int(m - k)));
}

double smooth_step(double z, double w, double* dg) {
  if (z <= -w) {
    if (dg) *dg = 0;
    return 0;
  }
  if (z >= w) {
    if (dg) *dg = 0;
    return 2;
  }
  const double t = z / w, t2 = t * t;
  if (dg) *dg = 15.0 * (1 - t2) * (1 - t2) / (8.0 * w);
  return 1.0 + t * (15.0 - 10.0 * t2 + 3.0 * t2 * t2) / 8.0;
}

double smooth_max(const double* z, std::size_t m, double width, double* dz) {
  if (m == 1) {
    if (dz) dz[0] = 1;
    return z[0];
  }
  // Weights w_i = Π_{j≠i} g(z_i - z_j). The largest value has every factor
  // >= 1, so Σ w >= 1.
  double wsum = 0, zw = 0;
  double wbuf[64];
  std::vector<double> wvec;
  double* w = wbuf;
  if (m > 64) {
    wvec.resize(m);
    w = wvec.data();
  }
  for (std::size_t i = 0; i < m; ++i) {
    double p = 1;
    for (std::size_t j = 0; j < m && p != 0; ++j)
      if (j != i) p *= smooth_step(z[i] - z[j], width);
    w[i] = p;
    wsum += p;
    zw += p * z[i];
  }
  const double s = zw / wsum;
  if (dz) {
    // ∂s/∂z_k = (w_k + Σ_i (z_i - s) ∂w_i/∂z_k) / W.
    for (std::size_t k = 0; k < m; ++k) dz[k] = w[k];
    for (std::size_t i = 0; i < m; ++i) {
      const double zi = z[i] - s;
      if (zi == 0) continue;
      for (std::size_t l = 0; l < m; ++l) {
        if (l == i) continue;
        double dgl = 0;
        smooth_step(z[i] - z[l], width, &dgl);
        if (dgl == 0) continue;
        double rest = 1;  // Π_{j≠i,l} g(z_i - z_j)
        for (std::size_t j = 0; j < m && rest != 0; ++j)
          if (j != i && j != l) rest *= smooth_step(z[i] - z[j], width);
        const double d = zi * dgl * rest;  // ∂w_i/∂z_i gets +, ∂w_i/∂z_l gets -
        dz[i] += d;
        dz[l] -= d;
      }
    }
    for (std::size_t k = 0; k < m; ++k) dz[k] /= wsum;
  }
  return s;
}

void sample_indicators(const MaterialSet& m, const Vec3& x, IndicatorSample& out) {
  const std::size_t n = m.fields.size();
  out.f.resize(n);
  out.grad.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 g;
    out.f[i] = -m.fields[i]->value_gradient(x, g);
    out.grad[i] = -g;
  }
}

double io_function(const IndicatorSample& s, std::size_t i, double width, Vec3* grad) {
  const std::size_t n = s.f.size();
  if (n <= 1) {
    if (grad) *grad = s.grad[i];
    return s.f[i];
  }
  std::vector<double> z;
  std::vector<std::size_t> idx;
  z.reserve(n - 1);
  idx.reserve(n - 1);
  for (std::size_t j = 0; j < n; ++j)
    if (j != i) {
      z.push_back(s.f[j]);
      idx.push_back(j);
    }
  std::vector<double> dz(grad ? z.size() : 0);
  const double sm = smooth_max(z.data(), z.size(), width, grad ? dz.data() : nullptr);
  if (grad) {
    Vec3 g = s.grad[i];
    for (std::size_t k = 0; k < z.size(); ++k) g -= s.grad[idx[k]] * dz[k];
    *grad = g;
  }
  return s.f[i] - sm;
}

bool JunctionCell::contains(int material) const {
  for (int k = 0; k < count; ++k)
    if (m[std::size_t(k)] == material) return true;
  return false;
}

bool JunctionCell::contains_all(const JunctionCell& other) const {
  for (int k = 0; k < other.count; ++k)
    if (!contains(other.m[std::size_t(k)])) return false;
  return true;
}

JunctionCell make_cell(std::vector<int> materials) {
  if (materials.size() < 2 || materials.size() > 4)
    throw UsageError("make_cell: a junction cell has 2 to 4 materials, got " + std::to_string(materials.size()));
  std::sort(materials.begin(), materials.end());
  JunctionCell c;
  c.count = int(materials.size());
  for (std::size_t k = 0; k < materials.size(); ++k) {
    if (materials[k] < 0) throw UsageError("make_cell: negative material index " + std::to_string(materials[k]));
    if (k && materials[k] == materials[k - 1])
      throw UsageError("make_cell: material " + std::to_string(materials[k]) + " appears twice");
    c.m[k] = materials[k];
  }
  return c;
}

double cell_indicator(const IndicatorSample& s, const JunctionCell& c, double width, Vec3* grad) {
  double j = 0;
  Vec3 g;
  for (int k = 0; k < c.count; ++k) {
    Vec3 gi;
    const double fi = io_function(s, std::size_t(c.m[std::size_t(k)]), width, grad ? &gi : nullptr);
    j += fi * fi;
    if (grad) g += gi * (2 * fi);
  }
  if (grad) *grad = g;
  return j;
}

Vec3 project_to_tangent(const JunctionCell& c, const std::array<Vec3, 4>& n, const Vec3& v) {
  if (c.count == 2) {
    const Vec3 d = normalized(n[0] - n[1]);
    return v - d * dot(d, v);
  }
  if (c.count == 3) {
    const Vec3 t = normalized(cross(n[0], n[1]) + cross(n[1], n[2]) + cross(n[2], n[0]));
    return t * dot(t, v);
  }
  return {};
}

namespace {

// Solve the symmetric positive definite k x k system G y = r (k <= 3) by
// Cholesky; false when G is (numerically) singular.
bool solve_spd(int k, double g[3][3], const double r[3], double y[3]) {
  double l[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  double scale = 0;
  for (int i = 0; i < k; ++i) scale = std::max(scale, g[i][i]);
  if (!(scale > 0) || !std::isfinite(scale)) return false;
  for (int i = 0; i < k; ++i) {
    for (int j = 0; j <= i; ++j) {
      double s = g[i][j];
      for (int q = 0; q < j; ++q) s -= l[i][q] * l[j][q];
      if (i == j) {
        if (!(s > 1e-12 * scale)) return false;
        l[i][i] = std::sqrt(s);
      } else {
        l[i][j] = s / l[j][j];
      }
    }
  }
  double t[3];
  for (int i = 0; i < k; ++i) {
    double s = r[i];
    for (int q = 0; q < i; ++q) s -= l[i][q] * t[q];
    t[i] = s / l[i][i];
  }
  for (int i = k - 1; i >= 0; --i) {
    double s = t[i];
    for (int q = i + 1; q < k; ++q) s -= l[q][i] * y[q];
    y[i] = s / l[i][i];
  }
  return true;
}

}  // namespace

CellProjection project_to_cell(const MaterialSet& m, const JunctionCell& c, const Vec3& x0,
                               const CellProjectParams& p) {
  CellProjection res;
  res.x = x0;
  const int k = c.count - 1;  // equations
  Vec3 x = x0;
  double f[4];
  Vec3 g[4];
  Vec3 rows[3];
  double r[3];
  for (int step = 0;; ++step) {
    bool finite = is_finite(x);
    for (int q = 0; q < c.count && finite; ++q) {
      Vec3 gq;
      f[q] = -m.fields[std::size_t(c.m[std::size_t(q)])]->value_gradient(x, gq);
      g[q] = -gq;
      ++res.evaluations;
      finite = std::isfinite(f[q]) && is_finite(g[q]);
    }
    if (!finite) {
      res.steps = step;
      return res;
    }
    double resid = 0;
    for (int q = 0; q < k; ++q) {
      r[q] = f[q] - f[q + 1];
      rows[q] = g[q] - g[q + 1];
      resid = std::max(resid, std::fabs(r[q]));
    }
    res.x = x;
    res.residual = resid;
    res.steps = step;
    res.value = f[0];
    if (resid <= p.tolerance) {
      res.converged = true;
      break;
    }
    if (step >= p.max_steps) return res;
    double gram[3][3];
    for (int a = 0; a < k; ++a)
      for (int b = 0; b < k; ++b) gram[a][b] = dot(rows[a], rows[b]);
    double y[3] = {0, 0, 0};
    if (!solve_spd(k, gram, r, y)) return res;
    Vec3 dx;
    for (int q = 0; q < k; ++q) dx -= rows[q] * y[q];
    if (p.max_step > 0) {
      const double len = norm(dx);
      if (len > p.max_step) dx *= p.max_step / len;
    }
    x += dx;
  }
  // Frame at the converged point.
  if (c.count == 2) res.frame = normalized(-rows[0]);
  else if (c.count == 3) res.frame = normalized(cross(rows[0], rows[1]));
  if (p.check_dominance) {
    res.dominant = true;
    const double top = f[0] + p.tolerance;  // f[0..count) agree within tolerance
    for (std::size_t o = 0; o < m.fields.size(); ++o) {
      if (c.contains(int(o))) continue;
      if (p.bounds && (*p.bounds)[o]) {
        // f_o = -d_o <= -lo(d_o): decided without evaluating when that is <= top.
        double lo, hi;
        if ((*p.bounds)[o]->at(res.x, lo, hi) && -lo <= top) {
          ++res.bounded;
          continue;
        }
      }
      const double fo = -m.fields[o]->value(res.x);
      ++res.evaluations;
      if (!(fo <= top)) {
        res.dominant = false;
        break;
      }
    }
  }
  return res;
}

}  // namespace pm
