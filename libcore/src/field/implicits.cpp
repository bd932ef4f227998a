#include "pm/field/implicits.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <sstream>
#include <utility>
#include <vector>

#include "pm/base/error.h"

namespace pm {

namespace {

Box centred_box(const Vec3& c, const Vec3& half) {
  Box b;
  b.extend(c - half);
  b.extend(c + half);
  return b;
}

// Bounding box plus 10% of its largest half-extent on every side.
Box with_margin(const Vec3& c, const Vec3& half) {
  const double m = 0.1 * std::max({half.x, half.y, half.z});
  return centred_box(c, half + Vec3(m, m, m));
}

// F = |x - c| - r. At the centre the gradient is undefined: 0 is returned.
class Sphere : public ScalarField {
 public:
  Sphere(double r, Vec3 c) : r_(r), c_(c) {}
  double value(const Vec3& x) const override { return norm(x - c_) - r_; }
  double value_gradient(const Vec3& x, Vec3& grad) const override {
    const Vec3 p = x - c_;
    const double d = norm(p);
    grad = d > 0 ? p / d : Vec3();
    return d - r_;
  }
  double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const override {
    const Vec3 p = x - c_;
    const double d = norm(p);
    if (!(d > 0)) {
      grad = Vec3();
      hess = Mat3();
      return -r_;
    }
    grad = p / d;
    hess = (Mat3::identity() - outer(grad, grad)) * (1.0 / d);
    return d - r_;
  }
  Box domain() const override { return with_margin(c_, Vec3(r_, r_, r_)); }
  double resolution() const override { return r_ / 50; }
  std::string describe() const override {
    return "sphere r=" + format_number(r_) + " c=(" + format_number(c_.x) + "," + format_number(c_.y) + "," + format_number(c_.z) + ")";
  }

 private:
  double r_;
  Vec3 c_;
};

// Distance to the core circle (radius R in the z = 0 plane) minus r:
// q = (rho - R, z), F = |q| - r with rho = sqrt(x² + y²). On the z axis the
// xy part of the gradient (and the 1/rho Hessian term) is set to 0; on the
// core circle the gradient is 0.
class Torus : public ScalarField {
 public:
  Torus(double R, double r) : R_(R), r_(r) {}
  double value(const Vec3& x) const override {
    const double q1 = std::hypot(x.x, x.y) - R_;
    return std::hypot(q1, x.z) - r_;
  }
  double value_gradient(const Vec3& x, Vec3& grad) const override {
    Mat3 unused;
    return eval(x, grad, unused, false);
  }
  double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const override {
    return eval(x, grad, hess, true);
  }
  Box domain() const override { return with_margin({}, Vec3(R_ + r_, R_ + r_, r_)); }
  double resolution() const override { return std::min(r_, R_ - r_) / 50; }
  std::string describe() const override { return "torus R=" + format_number(R_) + " r=" + format_number(r_); }

 private:
  double eval(const Vec3& x, Vec3& grad, Mat3& hess, bool want_hess) const {
    const double rho = std::hypot(x.x, x.y);
    const Vec3 e = rho > 0 ? Vec3(x.x / rho, x.y / rho, 0) : Vec3();
    const double q1 = rho - R_, q2 = x.z;
    const double d = std::hypot(q1, q2);
    if (!(d > 0)) {
      grad = Vec3();
      if (want_hess) hess = Mat3();
      return -r_;
    }
    const double m1 = q1 / d, m2 = q2 / d;
    const Vec3 ez(0, 0, 1);
    grad = m1 * e + m2 * ez;
    if (want_hess) {
      // H = (e eᵀ + ez ezᵀ - g gᵀ)/d + (m1/rho)(diag(1,1,0) - e eᵀ)
      hess = (outer(e, e) + outer(ez, ez) - outer(grad, grad)) * (1.0 / d);
      if (rho > 0) hess = hess + (Mat3::diag(1, 1, 0) - outer(e, e)) * (m1 / rho);
    }
    return d - r_;
  }
  double R_, r_;
};

// Tangle cube, F(x) = sum_i g(x_i/s) + 11.8 with g(u) = u⁴ - 5u² (not a
// distance). On the surface g(x_i/s) <= 2 * 6.25 - 11.8 = 0.7, so
// |x_i| <= s * sqrt((5 + sqrt(27.8))/2) ~ 2.266 s.
class Tangle : public ScalarField {
 public:
  explicit Tangle(double s) : s_(s) {}
  double value(const Vec3& x) const override {
    double f = 11.8;
    for (int i = 0; i < 3; ++i) {
      const double u = x[i] / s_, u2 = u * u;
      f += u2 * u2 - 5 * u2;
    }
    return f;
  }
  double value_gradient(const Vec3& x, Vec3& grad) const override {
    double f = 11.8;
    for (int i = 0; i < 3; ++i) {
      const double u = x[i] / s_, u2 = u * u;
      f += u2 * u2 - 5 * u2;
      grad[i] = (4 * u2 - 10) * u / s_;
    }
    return f;
  }
  double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const override {
    hess = Mat3();
    double f = 11.8;
    for (int i = 0; i < 3; ++i) {
      const double u = x[i] / s_, u2 = u * u;
      f += u2 * u2 - 5 * u2;
      grad[i] = (4 * u2 - 10) * u / s_;
      hess.m[i][i] = (12 * u2 - 10) / (s_ * s_);
    }
    return f;
  }
  Box domain() const override {
    const double h = s_ * std::sqrt(0.5 * (5 + std::sqrt(27.8)));
    return with_margin({}, Vec3(h, h, h));
  }
  double resolution() const override { return s_ / 50; }
  std::string describe() const override { return "tangle s=" + format_number(s_); }

 private:
  double s_;
};

// Rounded box centred at the origin, exact signed distance:
// q = |x| - (a-r, b-r, c-r); F = |max(q,0)| + min(max_i q_i, 0) - r.
// Inside the inner box the gradient is the outward axis of the largest q_i
// (first one on ties, + on a symmetry plane) and the Hessian is 0; over a
// face it is that axis and 0; near a rounded edge or corner it is the
// distance to that edge line or corner point.
class RoundedBox : public ScalarField {
 public:
  RoundedBox(double a, double b, double c, double r) : half_(a, b, c), r_(r) {}
  double value(const Vec3& x) const override {
    Vec3 g;
    Mat3 h;
    return eval(x, g, h, false);
  }
  double value_gradient(const Vec3& x, Vec3& grad) const override {
    Mat3 unused;
    return eval(x, grad, unused, false);
  }
  double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const override {
    return eval(x, grad, hess, true);
  }
  Box domain() const override { return with_margin({}, half_); }
  double resolution() const override { return r_ / 50; }
  std::string describe() const override {
    return "box a=" + format_number(half_.x) + " b=" + format_number(half_.y) + " c=" + format_number(half_.z) + " r=" + format_number(r_);
  }

 private:
  double eval(const Vec3& x, Vec3& grad, Mat3& hess, bool want_hess) const {
    Vec3 sgn, q, p;
    for (int i = 0; i < 3; ++i) {
      sgn[i] = x[i] < 0 ? -1.0 : 1.0;
      q[i] = std::fabs(x[i]) - (half_[i] - r_);
      p[i] = std::max(q[i], 0.0);
    }
    if (want_hess) hess = Mat3();
    const double plen = norm(p);
    if (plen > 0) {  // outside the inner box: distance to it, minus r
      const Vec3 u = p / plen;
      for (int i = 0; i < 3; ++i) grad[i] = sgn[i] * u[i];
      if (want_hess)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            if (p[i] > 0 && p[j] > 0)
              hess.m[i][j] = sgn[i] * sgn[j] * ((i == j ? 1.0 : 0.0) - u[i] * u[j]) / plen;
      return plen - r_;
    }
    int k = 0;
    for (int i = 1; i < 3; ++i)
      if (q[i] > q[k]) k = i;
    grad = Vec3();
    grad[k] = sgn[k];
    return q[k] - r_;
  }
  Vec3 half_;
  double r_;
};

// Union of two spheres of radius r centred at (±d/2, 0, 0) as the minimum of
// their distances: exact distance outside; the circle where they meet is a
// sharp crease (gradient jumps). Ties go to the sphere at -d/2.
class TwoSpheres : public ScalarField {
 public:
  TwoSpheres(double r, double d) : a_(r, Vec3(-d / 2, 0, 0)), b_(r, Vec3(d / 2, 0, 0)), r_(r), d_(d) {}
  double value(const Vec3& x) const override { return std::min(a_.value(x), b_.value(x)); }
  double value_gradient(const Vec3& x, Vec3& grad) const override {
    return x.x <= 0 ? a_.value_gradient(x, grad) : b_.value_gradient(x, grad);
  }
  double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const override {
    return x.x <= 0 ? a_.evaluate(x, grad, hess) : b_.evaluate(x, grad, hess);
  }
  Box domain() const override { return with_margin({}, Vec3(d_ / 2 + r_, r_, r_)); }
  double resolution() const override { return r_ / 50; }
  std::string describe() const override { return "twospheres r=" + format_number(r_) + " d=" + format_number(d_); }

 private:
  Sphere a_, b_;
  double r_, d_;
};

struct ParamSpec {
  const char* name;
  double fallback;
  bool positive;  // must be > 0 (all but centre coordinates)
};

struct ShapeSpec {
  const char* name;
  std::vector<ParamSpec> params;
  const char* help;
};

const std::vector<ShapeSpec>& shapes() {
  static const std::vector<ShapeSpec> list = {
      {"sphere",
       {{"r", 1, true}, {"cx", 0, false}, {"cy", 0, false}, {"cz", 0, false}},
       "sphere of radius r centred at (cx,cy,cz)"},
      {"torus", {{"R", 1, true}, {"r", 0.4, true}}, "torus around the z axis, tube radius r < R"},
      {"tangle", {{"s", 1, true}}, "tangle cube quartic scaled by s (not a distance)"},
      {"box", {{"a", 1, true}, {"b", 1, true}, {"c", 1, true}, {"r", 0.2, true}},
       "box with half-extents a,b,c rounded by r <= min(a,b,c)"},
      {"twospheres", {{"r", 1, true}, {"d", 1.2, true}},
       "two spheres at (+-d/2,0,0) joined at a sharp crease"},
  };
  return list;
}

std::string usage_of(const ShapeSpec& s) {
  std::string u = s.name;
  u += "[:";
  for (std::size_t i = 0; i < s.params.size(); ++i)
    u += (i ? "," : "") + std::string(s.params[i].name) + "=" + format_number(s.params[i].fallback);
  return u + "]";
}

std::string names_list() {
  std::string l;
  for (const auto& s : shapes()) l += (l.empty() ? "" : ", ") + std::string(s.name);
  return l;
}

}  // namespace

std::string implicit_help() {
  std::string h;
  for (const auto& s : shapes()) h += (h.empty() ? "" : "; ") + usage_of(s) + " " + s.help;
  return h + " (sphere, torus, box: signed distances; all F < 0 inside)";
}

std::unique_ptr<ScalarField> make_implicit(const std::string& spec) {
  const std::string where = "implicit " + quote(spec) + ": ";
  const std::size_t colon = spec.find(':');
  const std::string name = spec.substr(0, colon);
  const ShapeSpec* shape = nullptr;
  for (const auto& s : shapes())
    if (name == s.name) shape = &s;
  if (!shape)
    throw UsageError(where + "unknown implicit " + quote(name) + "; expected one of " + names_list() +
                     " (e.g. \"torus:R=1,r=0.4\")");

  std::string valid;
  for (const auto& p : shape->params) valid += (valid.empty() ? "" : ", ") + std::string(p.name);
  std::map<std::string, double> v;
  for (const auto& p : shape->params) v[p.name] = p.fallback;

  if (colon != std::string::npos) {
    const std::string args = spec.substr(colon + 1);
    std::vector<std::string> seen;
    std::size_t pos = 0;
    while (pos <= args.size()) {
      const std::size_t comma = std::min(args.find(',', pos), args.size());
      const std::string item = args.substr(pos, comma - pos);
      pos = comma + 1;
      const std::size_t eq = item.find('=');
      const std::string key = item.substr(0, eq);
      const ParamSpec* ps = nullptr;
      for (const auto& p : shape->params)
        if (key == p.name) ps = &p;
      if (!ps)
        throw UsageError(where + "unknown parameter " + quote(key) + " for " + name + "; expected " +
                         valid + " as " + usage_of(*shape));
      if (std::find(seen.begin(), seen.end(), key) != seen.end())
        throw UsageError(where + "parameter " + quote(key) + " given twice");
      seen.push_back(key);
      const std::string text = eq == std::string::npos ? std::string() : item.substr(eq + 1);
      char* end = nullptr;
      const double x = text.empty() ? 0.0 : std::strtod(text.c_str(), &end);
      if (text.empty() || *end != '\0' || !std::isfinite(x))
        throw UsageError(where + key + "=" + quote(text) + " is not a number; expected " + key +
                         "=<finite number>");
      if (ps->positive && !(x > 0))
        throw UsageError(where + key + " must be > 0, got " + format_number(x));
      v[key] = x;
    }
  }

  if (name == "sphere") return std::make_unique<Sphere>(v["r"], Vec3(v["cx"], v["cy"], v["cz"]));
  if (name == "torus") {
    if (!(v["r"] < v["R"]))
      throw UsageError(where + "tube radius r=" + format_number(v["r"]) + " must be < ring radius R=" +
                       format_number(v["R"]));
    return std::make_unique<Torus>(v["R"], v["r"]);
  }
  if (name == "tangle") return std::make_unique<Tangle>(v["s"]);
  if (name == "box") {
    const double m = std::min({v["a"], v["b"], v["c"]});
    if (v["r"] > m)
      throw UsageError(where + "rounding radius r=" + format_number(v["r"]) +
                       " must be <= the smallest half-extent " + format_number(m));
    return std::make_unique<RoundedBox>(v["a"], v["b"], v["c"], v["r"]);
  }
  return std::make_unique<TwoSpheres>(v["r"], v["d"]);
}

}  // namespace pm
