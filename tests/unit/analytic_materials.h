#pragma once
// Analytic material sets for the Chapter-6 tests (junctions, multiparticles):
// fields d_i = -f_i (negative inside material i) given in closed form.
#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "pm/field/field.h"
#include "pm/field/materials.h"

namespace pm::test {

/// A field from closed-form f(x) and ∇f(x) on a box (Hessian left zero).
class AnalyticField : public ScalarField {
 public:
  using Fn = std::function<double(const Vec3&, Vec3&)>;
  AnalyticField(Fn fn, Box box, double res, std::string name)
      : fn_(std::move(fn)), box_(box), res_(res), name_(std::move(name)) {}
  double value(const Vec3& x) const override {
    Vec3 g;
    return fn_(x, g);
  }
  double value_gradient(const Vec3& x, Vec3& g) const override { return fn_(x, g); }
  double evaluate(const Vec3& x, Vec3& g, Mat3& h) const override {
    h = Mat3{};
    return fn_(x, g);
  }
  Box domain() const override { return box_; }
  double resolution() const override { return res_; }
  std::string describe() const override { return name_; }

 private:
  Fn fn_;
  Box box_;
  double res_;
  std::string name_;
};

inline Box cube(double h) {
  Box b;
  b.lo = {-h, -h, -h};
  b.hi = {h, h, h};
  return b;
}

/// Material i with indicator f(x) (positive inside): stores d = -f.
inline void add_material(MaterialSet& m, int label, std::function<double(const Vec3&, Vec3&)> f, Box box,
                         double res = 0.05) {
  m.labels.push_back(label);
  m.fields.push_back(std::make_shared<AnalyticField>(
      [f](const Vec3& x, Vec3& g) {
        const double v = f(x, g);
        g = -g;
        return -v;
      },
      box, res, "material " + std::to_string(label)));
}

/// A background material: f = 0 everywhere (a material is inside where its
/// f is the largest, so the others show where their f > 0).
inline void add_background(MaterialSet& m, int label, double half = 1.0) {
  add_material(
      m, label,
      [](const Vec3&, Vec3& g) {
        g = {};
        return 0.0;
      },
      cube(half));
}

/// Three materials (labels 0, 1, 2) in 120° wedges around the z axis:
/// f_i = n_i·(x, y) + c (i - 1)(x² + y²), n_i at 90°, 210°, 330°. The z axis
/// is the triple line for any c; c != 0 curves the interfaces.
inline MaterialSet three_wedges(double c, double half = 1.0, double res = 0.05) {
  MaterialSet m;
  for (int i = 0; i < 3; ++i) {
    const double a = (90.0 + 120.0 * i) * M_PI / 180.0;
    const Vec3 n{std::cos(a), std::sin(a), 0};
    const double ci = c * (i - 1);
    add_material(
        m, i,
        [n, ci](const Vec3& x, Vec3& g) {
          g = n + Vec3{2 * ci * x.x, 2 * ci * x.y, 0};
          return dot(n, x) + ci * (x.x * x.x + x.y * x.y);
        },
        cube(half), res);
  }
  return m;
}

/// Unit tetrahedral directions (1,1,1), (1,-1,-1), (-1,1,-1), (-1,-1,1) / √3.
inline Vec3 tetra_direction(int i) {
  static const Vec3 d[4] = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
  return normalized(d[i]);
}

/// Four materials (labels 0..3) in cones around the tetrahedral directions,
/// f_i = n_i·x: a quadruple point at the origin, triple rays along -n_l.
inline MaterialSet four_tetrahedral(double half = 1.0) {
  MaterialSet m;
  for (int i = 0; i < 4; ++i) {
    const Vec3 n = tetra_direction(i);
    add_material(
        m, i,
        [n](const Vec3& x, Vec3& g) {
          g = n;
          return dot(n, x);
        },
        cube(half));
  }
  return m;
}

/// Indicator of a ball: f = r - |x - c| (positive inside), for add_material.
inline std::function<double(const Vec3&, Vec3&)> ball(Vec3 c, double r) {
  return [c, r](const Vec3& x, Vec3& g) {
    const Vec3 d = x - c;
    const double l = norm(d);
    g = l > 0 ? -(d / l) : Vec3{};
    return r - l;
  };
}

/// Background 0 (f = 0), sphere 1 (centre (-0.3,0,0), radius 0.5) and sphere
/// 2 (centre (0.3,0,0), radius 0.4), f = radius - distance to the centre. The
/// spheres overlap: their triple circle with the background lies at x = 0.075.
inline MaterialSet two_spheres(double half = 1.0) {
  MaterialSet m;
  add_background(m, 0, half);
  add_material(m, 1, ball({-0.3, 0, 0}, 0.5), cube(half));
  add_material(m, 2, ball({0.3, 0, 0}, 0.4), cube(half));
  return m;
}

}  // namespace pm::test
