#include "pm/mesh/quad_smooth.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "pm/base/error.h"
#include "pm/mesh/meshstats.h"
#include "pm/mesh/quad_mesh.h"

namespace pm {
namespace {

constexpr double kRadToDeg = 57.29577951308232;  // for max_fold_deg
constexpr double kGradientProbe = 1e-3;          // finite-difference probe, fraction of the mean edge length

int sides(const std::array<int, 4>& f) { return f[3] >= 0 ? 4 : 3; }

class Smoother {
 public:
  Smoother(PolyMesh& m, const ScalarField& f, double iso, const QuadSmoothParams& p) : m_(m), f_(f), iso_(iso), p_(p) {
    const std::size_t nv = m.vertices.size();
    // vertex -> faces (CSR), and the vertices on open or non-manifold edges.
    start_.assign(nv + 1, 0);
    for (const auto& f4 : m.faces)
      for (int k = 0; k < sides(f4); ++k) ++start_[std::size_t(f4[std::size_t(k)]) + 1];
    for (std::size_t v = 0; v < nv; ++v) start_[v + 1] += start_[v];
    faces_.resize(start_[nv]);
    std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < m.faces.size(); ++i)
      for (int k = 0; k < sides(m.faces[i]); ++k)
        faces_[fill[std::size_t(m.faces[i][std::size_t(k)])]++] = std::uint32_t(i);
    std::vector<std::uint64_t> edges;
    for (const auto& f4 : m.faces)
      for (int k = 0; k < sides(f4); ++k)
        edges.push_back(undirected_edge_key(f4[std::size_t(k)], f4[std::size_t((k + 1) % sides(f4))]));
    std::sort(edges.begin(), edges.end());
    pinned_.assign(nv, 0);
    double total = 0;
    std::size_t count = 0;
    for (std::size_t i = 0; i < edges.size();) {
      std::size_t j = i + 1;
      while (j < edges.size() && edges[j] == edges[i]) ++j;
      const int a = int(edges[i] >> 32), b = int(edges[i] & 0xffffffffu);
      if (j - i != 2) pinned_[std::size_t(a)] = pinned_[std::size_t(b)] = 1;
      total += norm(m.vertices[std::size_t(a)] - m.vertices[std::size_t(b)]);
      ++count;
      i = j;
    }
    tol_ = p.tolerance * (count ? total / double(count) : 1.0);
  }

  void freeze(std::size_t v) { pinned_[v] = 1; }

  QuadSmoothStats run() {
    QuadSmoothStats st;
    st.objective_before = total_objective();
    for (int pass = 0; pass < p_.passes; ++pass) {
      std::size_t moved = 0;
      for (std::size_t v = 0; v < m_.vertices.size(); ++v)
        if (!pinned_[v] && start_[v + 1] > start_[v] && relax(v, st)) ++moved;
      st.moves += moved;
      if (moved == 0) break;
    }
    st.objective_after = total_objective();
    return st;
  }

 private:
  // The two polygon neighbours of v in face f4 (previous, next).
  static std::pair<int, int> around(const std::array<int, 4>& f4, int v) {
    const int n = sides(f4);
    for (int k = 0; k < n; ++k)
      if (f4[std::size_t(k)] == v) return {f4[std::size_t((k + n - 1) % n)], f4[std::size_t((k + 1) % n)]};
    return {-1, -1};
  }

  // The objective of the faces around v with v at x (corners of those faces
  // and the edges at v against the reference length ref).
  double objective(std::size_t v, const Vec3& x, double ref) const {
    const Vec3 saved = m_.vertices[v];
    m_.vertices[v] = x;
    double e = 0;
    for (std::uint32_t k = start_[v]; k < start_[v + 1]; ++k) {
      const auto& f4 = m_.faces[faces_[k]];
      const int n = sides(f4);
      const double target = n == 4 ? 90.0 : 60.0;
      for (int c = 0; c < n; ++c) {
        const double a = corner_angle_deg(m_.vertices[std::size_t(f4[std::size_t((c + n - 1) % n)])],
                                          m_.vertices[std::size_t(f4[std::size_t(c)])],
                                          m_.vertices[std::size_t(f4[std::size_t((c + 1) % n)])]);
        const double d = (a - target) / 90.0;
        e += d * d;
      }
      // The edge from v to its next neighbour in this face: each edge at v is
      // the "next" edge of exactly one face of a closed manifold.
      const auto nb = around(f4, int(v));
      const double l = norm(m_.vertices[std::size_t(nb.second)] - x) / ref - 1;
      e += p_.length_weight * l * l;
    }
    m_.vertices[v] = saved;
    return e;
  }

  double mean_edge(std::size_t v) const {
    double s = 0;
    for (std::uint32_t k = start_[v]; k < start_[v + 1]; ++k)
      s += norm(m_.vertices[std::size_t(around(m_.faces[faces_[k]], int(v)).second)] - m_.vertices[v]);
    return s / double(start_[v + 1] - start_[v]);
  }

  bool project(Vec3& x) const {
    for (int s = 0; s <= p_.newton_steps; ++s) {
      Vec3 g;
      const double val = f_.value_gradient(x, g) - iso_;
      const double gg = norm2(g);
      if (!std::isfinite(val) || !(gg > 0)) return false;
      if (std::fabs(val) / std::sqrt(gg) <= tol_) return true;
      if (s == p_.newton_steps) break;
      x -= g * (val / gg);
    }
    return false;
  }

  // Faces around v stay unfolded and their quads' Jacobians above the floor.
  bool acceptable(std::size_t v, const Vec3& x, const std::vector<Vec3>& normals_before,
                  const std::vector<double>& jac_before) const {
    const Vec3 saved = m_.vertices[v];
    m_.vertices[v] = x;
    const double cos_fold = std::cos(p_.max_fold_deg / kRadToDeg);
    bool ok = true;
    for (std::uint32_t k = start_[v]; ok && k < start_[v + 1]; ++k) {
      const auto& f4 = m_.faces[faces_[k]];
      const Vec3 n = polygon_normal(m_.vertices, f4);
      const Vec3& n0 = normals_before[k - start_[v]];
      const double l = norm(n) * norm(n0);
      if (!(l > 0) || dot(n, n0) < cos_fold * l)
        ok = false;
      else if (polygon_scaled_jacobian(m_.vertices, f4) < std::min(jac_before[k - start_[v]], p_.min_jacobian))
        ok = false;
    }
    m_.vertices[v] = saved;
    return ok;
  }

  bool relax(std::size_t v, QuadSmoothStats& st) {
    const Vec3 x0 = m_.vertices[v];
    Vec3 g;
    f_.value_gradient(x0, g);
    const double lg = norm(g);
    if (!(lg > 0)) return false;
    const Vec3 n = g / lg;
    // Tangent basis.
    const Vec3 a = std::fabs(n.x) < 0.9 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
    const Vec3 t1 = normalized(cross(n, a)), t2 = cross(n, t1);
    const double ref = mean_edge(v);
    if (!(ref > 0)) return false;
    const double h = kGradientProbe * ref;
    const double e0 = objective(v, x0, ref);
    const double g1 = (objective(v, x0 + t1 * h, ref) - objective(v, x0 - t1 * h, ref)) / (2 * h);
    const double g2 = (objective(v, x0 + t2 * h, ref) - objective(v, x0 - t2 * h, ref)) / (2 * h);
    const double lgrad = std::hypot(g1, g2);
    if (!(lgrad > 0)) return false;
    const Vec3 dir = -(t1 * g1 + t2 * g2) / lgrad;
    const std::size_t nf = start_[v + 1] - start_[v];
    normals_.resize(nf);
    jac_.resize(nf);
    for (std::size_t k = 0; k < nf; ++k) {
      normals_[k] = polygon_normal(m_.vertices, m_.faces[faces_[start_[v] + k]]);
      jac_[k] = polygon_scaled_jacobian(m_.vertices, m_.faces[faces_[start_[v] + k]]);
    }
    double step = p_.step * ref;
    for (int s = 0; s <= p_.halvings; ++s, step *= 0.5) {
      const Vec3 tangent = x0 + dir * step;
      Vec3 x = tangent;
      // A projection that travels farther than half the step went to another sheet.
      if (!project(x) || norm(x - tangent) > 0.5 * step + 10 * tol_) {
        ++st.rejected;
        continue;
      }
      if (!(objective(v, x, ref) < e0) || !acceptable(v, x, normals_, jac_)) {
        ++st.rejected;
        continue;
      }
      m_.vertices[v] = x;
      return true;
    }
    return false;
  }

  double total_objective() const {
    double e = 0;
    for (const auto& f4 : m_.faces) {
      const int n = sides(f4);
      const double target = n == 4 ? 90.0 : 60.0;
      for (int c = 0; c < n; ++c) {
        const double d = (corner_angle_deg(m_.vertices[std::size_t(f4[std::size_t((c + n - 1) % n)])],
                                           m_.vertices[std::size_t(f4[std::size_t(c)])],
                                           m_.vertices[std::size_t(f4[std::size_t((c + 1) % n)])]) -
                          target) /
                         90.0;
        e += d * d;
      }
    }
    return e;
  }

  PolyMesh& m_;
  const ScalarField& f_;
  double iso_;
  QuadSmoothParams p_;
  double tol_ = 0;
  std::vector<std::uint32_t> start_, faces_;
  std::vector<char> pinned_;
  mutable std::vector<Vec3> normals_;
  mutable std::vector<double> jac_;
};

}  // namespace

namespace {

// Fan triangles of m (v0, vk, vk+1) with the polygon each came from.
Mesh fan_triangles(const PolyMesh& m, std::vector<int>& polygon) {
  Mesh t;
  t.vertices = m.vertices;
  polygon.clear();
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    const auto& q = m.faces[f];
    for (int k = 1; k + 1 < sides(q); ++k) {
      t.faces.push_back({q[0], q[std::size_t(k)], q[std::size_t(k + 1)]});
      polygon.push_back(int(f));
    }
  }
  return t;
}

}  // namespace

QuadSmoothStats smooth_quads(PolyMesh& m, const ScalarField& field, double iso, const QuadSmoothParams& p) {
  m.validate("smooth_quads");
  if (p.passes <= 0 || m.faces.empty()) return {};
  const std::vector<Vec3> start = m.vertices;
  std::vector<char> frozen(m.vertices.size(), 0);
  std::vector<int> polygon;
  std::vector<std::pair<int, int>> pairs;
  QuadSmoothStats st;
  for (int round = 0;; ++round) {
    m.vertices = start;
    Smoother s(m, field, iso, p);
    for (std::size_t v = 0; v < frozen.size(); ++v)
      if (frozen[v]) s.freeze(v);
    const QuadSmoothStats r = s.run();
    st.moves = r.moves;
    st.rejected += r.rejected;
    st.objective_after = r.objective_after;
    if (round == 0) st.objective_before = r.objective_before;
    pairs.clear();
    if (!self_intersecting_faces(fan_triangles(m, polygon), pairs)) {
      st.self_intersections = -1;
      break;
    }
    st.self_intersections = int(pairs.size());
    if (pairs.empty() || round == p.max_redos) break;
    std::size_t added = 0;
    for (const auto& [a, b] : pairs)
      for (const int t : {a, b}) {
        const auto& q = m.faces[std::size_t(polygon[std::size_t(t)])];
        for (int k = 0; k < sides(q); ++k) {
          char& f = frozen[std::size_t(q[std::size_t(k)])];
          added += !f;
          f = 1;
        }
      }
    if (added == 0) break;  // the crossings are the input's own
    ++st.redos;
  }
  for (char f : frozen) st.frozen += f != 0;
  return st;
}

}  // namespace pm
