#include "pm/ops/surface_improve.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "pm/base/error.h"
#include "pm/ops/meshstats.h"

namespace pm {

double triangle_radius_ratio(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double la = norm(b - c), lb = norm(c - a), lc = norm(a - b);
  const double area2 = norm(cross(b - a, c - a));  // twice the area
  const double prod = la * lb * lc, perim = la + lb + lc;
  if (!(prod > 0) || !(perim > 0)) return 0;
  // r_in = 2A / perimeter, r_circ = abc / 4A: 2 r_in / r_circ = 16 A² / (perimeter · abc).
  return 4.0 * area2 * area2 / (perim * prod);
}

namespace {

using Tri = std::array<int, 3>;

std::uint64_t undirected(int a, int b) {
  const std::uint32_t lo = std::uint32_t(std::min(a, b)), hi = std::uint32_t(std::max(a, b));
  return (std::uint64_t(hi) << 32) | lo;
}
std::uint64_t directed(int a, int b) { return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b); }

Vec3 face_normal(const Vec3& a, const Vec3& b, const Vec3& c) { return cross(b - a, c - a); }

class Improver {
 public:
  Improver(Mesh& m, const ScalarField& f, double iso, const SurfaceImproveParams& p, const std::vector<char>& frozen)
      : m_(m), f_(f), iso_(iso), p_(p), cos_fold_(std::cos(p.max_fold_deg * 3.14159265358979323846 / 180)),
        frozen_(frozen) {}

  SurfaceImproveStats run() {
    build_opposites();  // validates the mesh
    measure(st_.rr_min_before, st_.rr_mean_before, st_.valence6_before);
    double edge_sum = 0;
    for (const Tri& t : m_.faces)
      for (int k = 0; k < 3; ++k) edge_sum += norm(m_.vertices[t[k]] - m_.vertices[t[(k + 1) % 3]]);
    mean_edge_ = m_.faces.empty() ? 1.0 : edge_sum / (3.0 * double(m_.faces.size()));
    tol_ = p_.tolerance * mean_edge_;
    for (int r = 0; r < p_.rounds; ++r) {
      for (int pass = 0; pass < 8; ++pass) {
        if (flip_pass() == 0) break;
        build_opposites();
      }
      for (int s = 0; s < p_.smoothing_steps; ++s) smooth_step();
    }
    if (m_.has_normals()) update_normals();
    measure(st_.rr_min_after, st_.rr_mean_after, st_.valence6_after);
    return st_;
  }

 private:
  // Half-edge h = 3f + k runs from faces[f][k] to faces[f][k+1].
  void build_opposites() {
    const std::size_t nf = m_.faces.size();
    std::unordered_map<std::uint64_t, int> he;
    he.reserve(3 * nf);
    for (std::size_t f = 0; f < nf; ++f)
      for (int k = 0; k < 3; ++k) {
        const int a = m_.faces[f][k], b = m_.faces[f][(k + 1) % 3];
        if (!he.emplace(directed(a, b), int(3 * f + k)).second)
          throw InputError("improve_surface: edge (" + std::to_string(a) + ", " + std::to_string(b) +
                           ") is used twice in the same direction; expected a consistently oriented manifold");
      }
    opp_.assign(3 * nf, -1);
    edges_.clear();
    edges_.reserve(2 * nf);
    valence_.assign(m_.vertices.size(), 0);
    for (std::size_t f = 0; f < nf; ++f)
      for (int k = 0; k < 3; ++k) {
        const int a = m_.faces[f][k], b = m_.faces[f][(k + 1) % 3];
        const auto it = he.find(directed(b, a));
        if (it == he.end())
          throw InputError("improve_surface: edge (" + std::to_string(a) + ", " + std::to_string(b) +
                           ") borders one triangle; expected a closed surface");
        opp_[3 * f + k] = it->second;
        if (a < b) {
          edges_.insert(undirected(a, b));
          ++valence_[a];
          ++valence_[b];
        }
      }
  }

  // Distance-like deviation of a point from the surface: |F - iso| / |∇F|.
  double deviation(const Vec3& x) const {
    Vec3 g;
    const double v = f_.value_gradient(x, g) - iso_;
    const double gn = norm(g);
    return gn > 0 ? std::fabs(v) / gn : 1e300;
  }

  std::size_t flip_pass() {
    const std::size_t nf = m_.faces.size();
    std::vector<char> touched(nf, 0);
    std::size_t flips = 0;
    auto& V = m_.vertices;
    for (std::size_t h = 0; h < 3 * nf; ++h) {
      const std::size_t o = std::size_t(opp_[h]);
      if (o < h) continue;
      const std::size_t f = h / 3, g = o / 3;
      if (touched[f] || touched[g] || f == g) continue;
      const int k = int(h % 3), mo = int(o % 3);
      const int a = m_.faces[f][k], b = m_.faces[f][(k + 1) % 3], c = m_.faces[f][(k + 2) % 3];
      const int d = m_.faces[g][(mo + 2) % 3];
      if (c == d || valence_[a] <= 3 || valence_[b] <= 3 || edges_.count(undirected(c, d))) continue;
      if (frozen_[a] || frozen_[b] || frozen_[c] || frozen_[d]) continue;
      const Vec3 &A = V[a], &B = V[b], &C = V[c], &D = V[d];
      const double rr_old = std::min(triangle_radius_ratio(A, B, C), triangle_radius_ratio(B, A, D));
      const double rr_new = std::min(triangle_radius_ratio(A, D, C), triangle_radius_ratio(B, C, D));
      auto dev = [&](int v, int dv) {
        const double x = double(valence_[v] + dv - 6);
        return x * x;
      };
      const double dev_old = dev(a, 0) + dev(b, 0) + dev(c, 0) + dev(d, 0);
      const double dev_new = dev(a, -1) + dev(b, -1) + dev(c, 1) + dev(d, 1);
      const bool quality_flip = rr_old < p_.poor && rr_new > p_.quality_gain * rr_old && dev_new <= dev_old + 2;
      const bool valence_flip = dev_new < dev_old && rr_new >= p_.keep_quality * rr_old;
      if (!quality_flip && !valence_flip) continue;
      // No fold: the new triangles face the way the old pair did and each other.
      const Vec3 n_old = normalized(normalized(face_normal(A, B, C)) + normalized(face_normal(B, A, D)));
      const Vec3 n1 = normalized(face_normal(A, D, C)), n2 = normalized(face_normal(B, C, D));
      if (!(dot(n1, n_old) >= cos_fold_ && dot(n2, n_old) >= cos_fold_ && dot(n1, n2) >= cos_fold_)) continue;
      // The new edge must follow the surface about as well as the old one.
      const double dev_cd = deviation((C + D) * 0.5), dev_ab = deviation((A + B) * 0.5);
      if (!(dev_cd <= std::max(1.5 * dev_ab, 0.02 * norm(C - D)))) continue;
      m_.faces[f] = {a, d, c};
      m_.faces[g] = {b, c, d};
      touched[f] = touched[g] = 1;
      edges_.erase(undirected(a, b));
      edges_.insert(undirected(c, d));
      --valence_[a];
      --valence_[b];
      ++valence_[c];
      ++valence_[d];
      ++flips;
    }
    st_.flips += flips;
    return flips;
  }

  // Newton projection onto F = iso; false when it does not get within tol_.
  bool project(Vec3& x) const {
    for (int s = 0; s <= p_.newton_steps; ++s) {
      Vec3 g;
      const double v = f_.value_gradient(x, g) - iso_;
      const double gg = norm2(g);
      if (!std::isfinite(v) || !(gg > 0)) return false;
      if (std::fabs(v) / std::sqrt(gg) <= tol_) return true;
      if (s == p_.newton_steps) break;
      x -= g * (v / gg);
    }
    return false;
  }

  void smooth_step() {
    const std::size_t nv = m_.vertices.size(), nf = m_.faces.size();
    // vertex -> faces (CSR)
    std::vector<std::uint32_t> start(nv + 1, 0), list(3 * nf);
    for (const Tri& t : m_.faces)
      for (int v : t) ++start[std::size_t(v) + 1];
    for (std::size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
    {
      std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
      for (std::size_t f = 0; f < nf; ++f)
        for (int v : m_.faces[f]) list[fill[std::size_t(v)]++] = std::uint32_t(f);
    }
    auto& V = m_.vertices;
    // Proposals in parallel (pure reads): tangential move towards the
    // area-weighted centroid of the 1-ring's triangles, projected onto F = iso.
    std::vector<Vec3> prop(nv);
    std::vector<char> ok(nv, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nv, 256), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t v = r.begin(); v != r.end(); ++v) {
        if (start[v] == start[v + 1] || frozen_[v] >= 2) continue;
        Vec3 sum;
        double wsum = 0;
        for (std::uint32_t q = start[v]; q < start[v + 1]; ++q) {
          const Tri& t = m_.faces[list[q]];
          const double area = norm(face_normal(V[t[0]], V[t[1]], V[t[2]]));
          sum += (V[t[0]] + V[t[1]] + V[t[2]]) * (area / 3.0);
          wsum += area;
        }
        if (!(wsum > 0)) continue;
        Vec3 g;
        f_.value_gradient(V[v], g);
        const Vec3 n = normalized(g);
        Vec3 step = (sum / wsum - V[v]) * p_.smoothing;
        step -= n * dot(n, step);
        const Vec3 tangent = V[v] + step;
        Vec3 x = tangent;
        // The surface departs from the tangent plane by about |step|² κ / 2;
        // a projection that travels farther went to another sheet (thin parts).
        if (!is_finite(x) || !project(x) || norm(x - tangent) > 0.5 * norm(step) + 10 * tol_) continue;
        prop[v] = x;
        ok[v] = 1;
      }
    });
    // Apply in vertex order against the current positions (deterministic): a
    // move may not fold a triangle or lower the 1-ring's worst radius ratio
    // below min(its old value, 0.5).
    for (std::size_t v = 0; v < nv; ++v) {
      if (!ok[v]) {
        if (start[v] != start[v + 1] && frozen_[v] < 2) ++st_.rejected_moves;
        continue;
      }
      const Vec3 old = V[v];
      double rr_old = 1, rr_new = 1;
      bool fold = false;
      for (std::uint32_t q = start[v]; q < start[v + 1] && !fold; ++q) {
        const Tri& t = m_.faces[list[q]];
        const Vec3 n0 = face_normal(V[t[0]], V[t[1]], V[t[2]]);
        rr_old = std::min(rr_old, triangle_radius_ratio(V[t[0]], V[t[1]], V[t[2]]));
        V[v] = prop[v];
        const Vec3 n1 = face_normal(V[t[0]], V[t[1]], V[t[2]]);
        rr_new = std::min(rr_new, triangle_radius_ratio(V[t[0]], V[t[1]], V[t[2]]));
        V[v] = old;
        const double l0 = norm(n0), l1 = norm(n1);
        fold = !(l0 > 0 && l1 > 0 && dot(n0, n1) >= cos_fold_ * l0 * l1);
      }
      if (fold || rr_new < std::min(rr_old, 0.5)) {
        ++st_.rejected_moves;
        continue;
      }
      V[v] = prop[v];
      ++st_.moves;
    }
  }

  void update_normals() {
    auto& V = m_.vertices;
    auto& N = m_.normals;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, V.size(), 512), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t v = r.begin(); v != r.end(); ++v) {
        Vec3 g;
        f_.value_gradient(V[v], g);
        const Vec3 n = normalized(g);
        if (is_finite(n) && norm2(n) > 0) N[v] = dot(n, N[v]) < 0 ? n * -1.0 : n;
      }
    });
  }

  void measure(double& rr_min, double& rr_mean, double& v6) const {
    rr_min = 1;
    double sum = 0;
    for (const Tri& t : m_.faces) {
      const double rr = triangle_radius_ratio(m_.vertices[t[0]], m_.vertices[t[1]], m_.vertices[t[2]]);
      rr_min = std::min(rr_min, rr);
      sum += rr;
    }
    rr_mean = m_.faces.empty() ? 0 : sum / double(m_.faces.size());
    std::size_t used = 0, six = 0;
    for (int val : valence_)
      if (val > 0) {
        ++used;
        six += val == 6;
      }
    v6 = used ? double(six) / double(used) : 0;
  }

  Mesh& m_;
  const ScalarField& f_;
  double iso_;
  SurfaceImproveParams p_;
  double cos_fold_;
  double mean_edge_ = 1, tol_ = 0;
  std::vector<int> opp_;
  std::unordered_set<std::uint64_t> edges_;
  std::vector<int> valence_;
  const std::vector<char>& frozen_;
  SurfaceImproveStats st_;
};

}  // namespace

SurfaceImproveStats improve_surface(Mesh& mesh, const ScalarField& field, double iso, const SurfaceImproveParams& p) {
  mesh.validate("improve_surface");
  if (p.rounds < 0 || p.smoothing_steps < 0 || !(p.smoothing >= 0 && p.smoothing <= 1))
    throw UsageError("improve_surface: rounds and smoothing steps must be >= 0 and smoothing in [0, 1]");
  // Flips and moves are local tests; where two sheets of the surface are
  // closer than an edge (thin parts), they can still make triangles cross.
  // Check with CGAL, freeze the vertices around every new crossing (and
  // their 1-rings), and redo from the original mesh; a few rounds suffice.
  const Mesh original = mesh;
  std::vector<std::pair<int, int>> pairs;
  self_intersecting_faces(original, pairs);
  const std::size_t before = pairs.size();
  std::vector<char> frozen(mesh.vertices.size(), 0);
  SurfaceImproveStats st;
  for (int attempt = 0;; ++attempt) {
    Improver im(mesh, field, iso, p, frozen);
    st = im.run();
    if (!self_intersecting_faces(mesh, pairs))
      throw InputError("improve_surface: the improved mesh is not a manifold polygon mesh (internal error)");
    st.self_intersections = pairs.size();
    if (pairs.size() <= before || attempt == 4) break;
    std::vector<char> seed(mesh.vertices.size(), 0);
    for (const auto& fp : pairs)
      for (int f : {fp.first, fp.second})
        for (int v : mesh.faces[std::size_t(f)]) seed[std::size_t(v)] = 1;
    // First no flips around the crossing, then (if it persists) no moves either.
    std::vector<char> grow(mesh.vertices.size(), 0);
    for (const Mesh* m : {static_cast<const Mesh*>(&mesh), &original})
      for (const auto& t : m->faces)
        if (seed[std::size_t(t[0])] || seed[std::size_t(t[1])] || seed[std::size_t(t[2])])
          for (int v : t) grow[std::size_t(v)] = 1;
    for (std::size_t v = 0; v < grow.size(); ++v)
      if (grow[v] && frozen[v] < 2) ++frozen[v];
    mesh = original;
  }
  st.self_intersections_before = before;
  for (char c : frozen) st.frozen += c != 0;
  return st;
}

}  // namespace pm
