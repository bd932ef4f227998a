#include "pm/mesh/surface_improve.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "pm/base/error.h"
#include "pm/base/parallel.h"
#include "pm/field/junctions.h"
#include "pm/mesh/meshstats.h"
#include "pm/mesh/topology.h"

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

// A set of undirected edge keys (undirected()): open addressing with linear
// probing and tombstones in one flat table, no allocation per edge (the
// surfaces have hundreds of thousands of edges, inserted anew every round).
class EdgeSet {
 public:
  void reset(std::size_t expected) {
    std::size_t size = 16;
    while (size < 2 * expected) size *= 2;
    slots_.assign(size, kEmpty);
    used_ = 0;
  }
  bool count(std::uint64_t key) const {
    for (std::size_t h = slot(key);; h = (h + 1) & (slots_.size() - 1)) {
      if (slots_[h] == key) return true;
      if (slots_[h] == kEmpty) return false;
    }
  }
  void insert(std::uint64_t key) {
    if (2 * (used_ + 1) > slots_.size()) grow();
    std::size_t tomb = kNone;
    for (std::size_t h = slot(key);; h = (h + 1) & (slots_.size() - 1)) {
      if (slots_[h] == key) return;
      if (slots_[h] == kTomb && tomb == kNone) tomb = h;
      if (slots_[h] == kEmpty) {
        if (tomb != kNone) {
          slots_[tomb] = key;
        } else {
          slots_[h] = key;
          ++used_;  // tombstones keep counting as used until the next grow
        }
        return;
      }
    }
  }
  void erase(std::uint64_t key) {
    for (std::size_t h = slot(key);; h = (h + 1) & (slots_.size() - 1)) {
      if (slots_[h] == key) {
        slots_[h] = kTomb;
        return;
      }
      if (slots_[h] == kEmpty) return;
    }
  }

 private:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t(0), kTomb = kEmpty - 1;
  static constexpr std::size_t kNone = ~std::size_t(0);
  std::size_t slot(std::uint64_t key) const {
    key ^= key >> 33;
    key *= 0xff51afd7ed558ccdull;
    key ^= key >> 33;
    return std::size_t(key) & (slots_.size() - 1);
  }
  void grow() {
    std::vector<std::uint64_t> old;
    old.swap(slots_);
    reset(old.size());
    for (std::uint64_t k : old)
      if (k != kEmpty && k != kTomb) insert(k);
  }
  std::vector<std::uint64_t> slots_;
  std::size_t used_ = 0;
};

std::uint64_t undirected(int a, int b) {
  const std::uint32_t lo = std::uint32_t(std::min(a, b)), hi = std::uint32_t(std::max(a, b));
  return (std::uint64_t(hi) << 32) | lo;
}

Vec3 face_normal(const Vec3& a, const Vec3& b, const Vec3& c) { return cross(b - a, c - a); }

// What the faces sample: face f lies on the zero set of sheet group[f],
// eval(x, group, grad) returning its value and gradient (F - iso for one
// surface; f_a - f_b between materials a and b).
struct Sheets {
  std::vector<int> group;  // per face
  std::function<double(const Vec3&, int, Vec3&)> eval;
  // Interfaces only: the two materials of each face, and the projection of a
  // point onto the triple curve of three materials (false when it fails).
  std::vector<std::array<int, 2>> face_labels;
  std::function<bool(Vec3&, const std::array<int, 3>&)> project_curve;
};

class Improver {
 public:
  Improver(Mesh& m, const Sheets& sh, bool single, const SurfaceImproveParams& p, const std::vector<char>& frozen)
      : m_(m), sh_(sh), single_(single), p_(p), cos_fold_(std::cos(p.max_fold_deg * 3.14159265358979323846 / 180)),
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
      for (int pass = 0; pass < 8; ++pass)
        if (flip_pass() == 0) break;  // flips keep opp_, edges_ and valence_ up to date
      for (int s = 0; s < p_.smoothing_steps; ++s) smooth_step();
    }
    if (single_ && m_.has_normals()) update_normals();
    measure(st_.rr_min_after, st_.rr_mean_after, st_.valence6_after);
    return st_;
  }

 private:
  // Half-edge h = 3f + k runs from faces[f][k] to faces[f][k+1].
  void build_opposites() {
    const std::size_t nf = m_.faces.size(), nv = m_.vertices.size();
    // Half-edges grouped by undirected edge: sorted (key, half-edge) pairs,
    // no allocation per edge.
    halves_.clear();
    halves_.reserve(3 * nf);
    for (std::size_t f = 0; f < nf; ++f)
      for (int k = 0; k < 3; ++k)
        halves_.push_back({undirected(m_.faces[f][k], m_.faces[f][(k + 1) % 3]), int(3 * f + k)});
    std::sort(halves_.begin(), halves_.end());
    opp_.assign(3 * nf, -1);
    edges_.reset(halves_.size() / 2 + 1);
    valence_.assign(nv, 0);
    fixed_.assign(nv, 0);
    curve_nb_.assign(nv, {-1, -1});
    std::vector<int> junction_edges(nv, 0);
    std::vector<int> vgroup(nv, -1);
    for (std::size_t f = 0; f < nf; ++f)
      for (int v : m_.faces[f]) {
        if (vgroup[v] == -1) vgroup[v] = sh_.group[f];
        else if (vgroup[v] != sh_.group[f]) fixed_[v] = 1;  // on a junction between sheets
      }
    std::vector<int> hs;
    for (std::size_t i = 0; i < halves_.size();) {
      const std::uint64_t key = halves_[i].first;
      hs.clear();
      for (; i < halves_.size() && halves_[i].first == key; ++i) hs.push_back(halves_[i].second);
      edges_.insert(key);
      const int a = int(key & 0xffffffffu), b = int(key >> 32);
      ++valence_[a];
      ++valence_[b];
      const auto from = [&](int h) { return m_.faces[std::size_t(h / 3)][h % 3]; };
      if (hs.size() == 2 && from(hs[0]) != from(hs[1]) && sh_.group[hs[0] / 3] == sh_.group[hs[1] / 3]) {
        opp_[hs[0]] = hs[1];
        opp_[hs[1]] = hs[0];
      } else {
        fixed_[a] = fixed_[b] = 1;  // boundary, junction curve or inconsistent orientation
        if (hs.size() >= 3)
          for (const auto& [u, w] : {std::make_pair(a, b), std::make_pair(b, a)}) {
            if (junction_edges[u] < 2) curve_nb_[u][junction_edges[u]] = w;
            ++junction_edges[u];
          }
        if (single_ && hs.size() == 1)
          throw InputError("improve_surface: edge (" + std::to_string(a) + ", " + std::to_string(b) +
                           ") borders one triangle; expected a closed surface");
        if (single_ && (hs.size() != 2 || from(hs[0]) == from(hs[1])))
          throw InputError("improve_surface: edge (" + std::to_string(a) + ", " + std::to_string(b) + ") has " +
                           std::to_string(hs.size()) + " triangles" +
                           (hs.size() == 2 ? " oriented the same way" : "") +
                           "; expected a closed, consistently oriented manifold");
      }
    }
    curve_count_ = std::move(junction_edges);
  }

  // A vertex inside a triple curve: exactly two junction edges, and its
  // faces show exactly three materials (returned sorted).
  bool curve_vertex(std::size_t v, const std::uint32_t* faces, std::size_t count, std::array<int, 3>& mats) const {
    if (!sh_.project_curve || curve_nb_[v][1] < 0 || curve_count(v) != 2) return false;
    int n = 0;
    for (std::size_t q = 0; q < count; ++q)
      for (int l : sh_.face_labels[faces[q]]) {
        bool seen = false;
        for (int k = 0; k < n; ++k) seen |= mats[std::size_t(k)] == l;
        if (seen) continue;
        if (n == 3) return false;
        mats[std::size_t(n++)] = l;
      }
    if (n != 3) return false;
    std::sort(mats.begin(), mats.end());
    return true;
  }
  int curve_count(std::size_t v) const { return curve_count_.empty() ? 0 : curve_count_[v]; }

  // Distance-like deviation of a point from the surface: |F - iso| / |∇F|.
  double deviation(const Vec3& x, int group) const {
    Vec3 g;
    const double v = sh_.eval(x, group, g);
    const double gn = norm(g);
    return gn > 0 ? std::fabs(v) / gn : 1e300;
  }

  std::size_t flip_pass() {
    const std::size_t nf = m_.faces.size();
    std::vector<char> touched(nf, 0);
    std::size_t flips = 0;
    auto& V = m_.vertices;
    // Each face's radius ratio, a filter only: an edge between two faces far
    // from poor whose flip would not improve the valences is skipped without
    // computing its own (vertex-order dependent) radius ratios. Faces change
    // in this pass only by flips, after which they are not visited again.
    rr_face_.resize(nf);
    pm::parallel_for(std::size_t(0), nf, [&](std::size_t f) {
      const Tri& t = m_.faces[f];
      rr_face_[f] = triangle_radius_ratio(V[t[0]], V[t[1]], V[t[2]]);
    });
    const double clearly_fine = p_.poor * (1 + 1e-9);
    for (std::size_t h = 0; h < 3 * nf; ++h) {
      if (opp_[h] < 0) continue;
      const std::size_t o = std::size_t(opp_[h]);
      if (o < h) continue;
      const std::size_t f = h / 3, g = o / 3;
      if (touched[f] || touched[g] || f == g) continue;
      const int k = int(h % 3), mo = int(o % 3);
      const int a = m_.faces[f][k], b = m_.faces[f][(k + 1) % 3], c = m_.faces[f][(k + 2) % 3];
      const int d = m_.faces[g][(mo + 2) % 3];
      if (c == d || valence_[a] <= 3 || valence_[b] <= 3) continue;
      if (frozen_[a] || frozen_[b] || frozen_[c] || frozen_[d]) continue;
      // Valence 6 is the goal on a sheet; junction vertices do not count.
      auto dev = [&](int v, int dv) {
        if (fixed_[v]) return 0.0;
        const double x = double(valence_[v] + dv - 6);
        return x * x;
      };
      const double dev_old = dev(a, 0) + dev(b, 0) + dev(c, 0) + dev(d, 0);
      const double dev_new = dev(a, -1) + dev(b, -1) + dev(c, 1) + dev(d, 1);
      // The cheap tests first: most edges are neither poor nor off valence.
      const bool fewer_off = dev_new < dev_old;
      if (!fewer_off && rr_face_[f] >= clearly_fine && rr_face_[g] >= clearly_fine) continue;
      const Vec3 &A = V[a], &B = V[b], &C = V[c], &D = V[d];
      const double rr_old = std::min(triangle_radius_ratio(A, B, C), triangle_radius_ratio(B, A, D));
      const bool poor = rr_old < p_.poor;
      if (!poor && !fewer_off) continue;
      const double rr_new = std::min(triangle_radius_ratio(A, D, C), triangle_radius_ratio(B, C, D));
      const bool better = poor && rr_new > p_.quality_gain * rr_old;
      // Never below min(old, 0.5): the mesh's worst triangle never gets worse
      // than that (the same rule as the smoothing's).
      const bool valence_flip = fewer_off && rr_new >= std::max(p_.keep_quality * rr_old, std::min(rr_old, 0.5));
      if (!better && !valence_flip) continue;
      // A folded pair (its triangles face apart: a fin the Delaunay surface
      // leaves where three particles line up on a tight bend) is unfolded
      // whatever the valences.
      const Vec3 nf_old = normalized(face_normal(A, B, C)), ng_old = normalized(face_normal(B, A, D));
      const bool folded = dot(nf_old, ng_old) < 0;
      const bool quality_flip = better && (folded || dev_new <= dev_old + 2);
      if (!quality_flip && !valence_flip) continue;
      // Only now the edge table (a cache miss per lookup): most edges fail the tests above.
      if (edges_.count(undirected(c, d))) continue;
      // No fold: the new triangles face the way the old pair did and each
      // other. A folded pair has no direction of its own: its four outer
      // neighbours give it.
      Vec3 n_old = normalized(nf_old + ng_old);
      if (folded) {
        Vec3 around;
        for (const int out : {opp_[3 * f + (k + 1) % 3], opp_[3 * f + (k + 2) % 3], opp_[3 * g + (mo + 1) % 3],
                              opp_[3 * g + (mo + 2) % 3]}) {
          if (out < 0) continue;
          const auto& t = m_.faces[std::size_t(out) / 3];
          around += normalized(face_normal(V[t[0]], V[t[1]], V[t[2]]));
        }
        n_old = normalized(around);
      }
      const Vec3 n1 = normalized(face_normal(A, D, C)), n2 = normalized(face_normal(B, C, D));
      if (!(dot(n1, n_old) >= cos_fold_ && dot(n2, n_old) >= cos_fold_ && dot(n1, n2) >= cos_fold_)) continue;
      // The new edge must follow the surface about as well as the old one.
      const int grp = sh_.group[f];
      const double dev_cd = deviation((C + D) * 0.5, grp), dev_ab = deviation((A + B) * 0.5, grp);
      if (!(dev_cd <= std::max(1.5 * dev_ab, 0.02 * norm(C - D)))) continue;
      // Re-link the opposites locally (what build_opposites would find: the
      // new edge c-d is not an edge yet, so it gets exactly these two halves).
      // Old f = (a b c) from k: a->b, b->c, c->a; old g from mo: b->a, a->d,
      // d->b. New f = (a d c): a->d, d->c, c->a; new g = (b c d): b->c, c->d, d->b.
      const int out_ad = opp_[3 * g + (mo + 1) % 3], out_ca = opp_[3 * f + (k + 2) % 3];
      const int out_bc = opp_[3 * f + (k + 1) % 3], out_db = opp_[3 * g + (mo + 2) % 3];
      m_.faces[f] = {a, d, c};
      m_.faces[g] = {b, c, d};
      const auto link = [&](std::size_t h_new, int other) {
        opp_[h_new] = other;
        if (other >= 0) opp_[std::size_t(other)] = int(h_new);
      };
      link(3 * f + 0, out_ad);
      link(3 * f + 2, out_ca);
      link(3 * g + 0, out_bc);
      link(3 * g + 2, out_db);
      link(3 * f + 1, int(3 * g + 1));
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
  bool project(Vec3& x, int group) const {
    for (int s = 0; s <= p_.newton_steps; ++s) {
      Vec3 g;
      const double v = sh_.eval(x, group, g);
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
    pm::parallel_for(tbb::blocked_range<std::size_t>(0, nv, 256), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t v = r.begin(); v != r.end(); ++v) {
        if (start[v] == start[v + 1] || frozen_[v] >= 2) continue;
        std::array<int, 3> mats;
        if (fixed_[v]) {
          // A triple-curve vertex slides along the curve towards the middle of
          // its two curve neighbours and is projected back onto the curve.
          if (!curve_vertex(v, &list[start[v]], start[v + 1] - start[v], mats)) continue;
          const Vec3 &p = V[std::size_t(curve_nb_[v][0])], &q = V[std::size_t(curve_nb_[v][1])];
          const Vec3 t = normalized(q - p);
          if (!is_finite(t)) continue;
          const Vec3 step = t * (dot(t, (p + q) * 0.5 - V[v]) * p_.smoothing);
          const Vec3 along = V[v] + step;
          Vec3 x = along;
          if (!sh_.project_curve(x, mats) || norm(x - along) > 0.5 * norm(step) + 10 * tol_) continue;
          prop[v] = x;
          ok[v] = 1;
          continue;
        }
        const int grp = sh_.group[list[start[v]]];
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
        sh_.eval(V[v], grp, g);
        const Vec3 n = normalized(g);
        Vec3 step = (sum / wsum - V[v]) * p_.smoothing;
        step -= n * dot(n, step);
        const Vec3 tangent = V[v] + step;
        Vec3 x = tangent;
        // The surface departs from the tangent plane by about |step|² κ / 2;
        // a projection that travels farther went to another sheet (thin parts).
        if (!is_finite(x) || !project(x, grp) || norm(x - tangent) > 0.5 * norm(step) + 10 * tol_) continue;
        prop[v] = x;
        ok[v] = 1;
      }
    });
    // Apply in vertex order against the current positions (deterministic): a
    // move may not fold a triangle or lower the 1-ring's worst radius ratio
    // below min(its old value, 0.5).
    for (std::size_t v = 0; v < nv; ++v) {
      if (!ok[v]) {
        if (start[v] != start[v + 1] && frozen_[v] < 2 && !fixed_[v]) ++st_.rejected_moves;  // curve vertices not counted
        continue;
      }
      const Vec3 old = V[v];
      double rr_old = 1, rr_new = 1;
      bool fold = false;
      for (std::uint32_t q = start[v]; q < start[v + 1]; ++q) {
        const Tri& t = m_.faces[list[q]];
        const Vec3 n0 = face_normal(V[t[0]], V[t[1]], V[t[2]]);
        rr_old = std::min(rr_old, triangle_radius_ratio(V[t[0]], V[t[1]], V[t[2]]));
        V[v] = prop[v];
        const Vec3 n1 = face_normal(V[t[0]], V[t[1]], V[t[2]]);
        rr_new = std::min(rr_new, triangle_radius_ratio(V[t[0]], V[t[1]], V[t[2]]));
        V[v] = old;
        const double l0 = norm(n0), l1 = norm(n1);
        fold = fold || !(l0 > 0 && l1 > 0 && dot(n0, n1) >= cos_fold_ * l0 * l1);
      }
      const bool unfolding = fold && unfolds(v, prop[v], &list[start[v]], start[v + 1] - start[v]);
      if ((fold && !unfolding) || rr_new < std::min(rr_old, 0.5)) {
        ++st_.rejected_moves;
        continue;
      }
      V[v] = prop[v];
      ++st_.moves;
      st_.unfolded += unfolding;
    }
  }

  // A move that turns a triangle around is a fold, unless that triangle
  // was the one turned around: it faced against its star (the sum of the
  // star's normals), and the move sets it, and every other triangle of the
  // star, within the fold angle of that direction. A particle that landed a
  // little past its neighbours on a tight bend leaves such an inverted
  // sliver, which only a move of its vertices repairs.
  bool unfolds(std::size_t v, const Vec3& to, const std::uint32_t* star, std::size_t n) {
    auto& V = m_.vertices;
    Vec3 sum;
    for (std::size_t q = 0; q < n; ++q) {
      const Tri& t = m_.faces[star[q]];
      sum += face_normal(V[t[0]], V[t[1]], V[t[2]]);
    }
    const double ls = norm(sum);
    if (!(ls > 0)) return false;
    const Vec3 old = V[v];
    bool inverted_before = false, ok = true;
    for (std::size_t q = 0; q < n && ok; ++q) {
      const Tri& t = m_.faces[star[q]];
      inverted_before = inverted_before || dot(face_normal(V[t[0]], V[t[1]], V[t[2]]), sum) < 0;
      V[v] = to;
      const Vec3 n1 = face_normal(V[t[0]], V[t[1]], V[t[2]]);
      V[v] = old;
      const double l1 = norm(n1);
      ok = l1 > 0 && dot(n1, sum) >= cos_fold_ * l1 * ls;
    }
    return ok && inverted_before;
  }

  void update_normals() {
    auto& V = m_.vertices;
    auto& N = m_.normals;
    pm::parallel_for(tbb::blocked_range<std::size_t>(0, V.size(), 512), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t v = r.begin(); v != r.end(); ++v) {
        Vec3 g;
        sh_.eval(V[v], 0, g);
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
    for (std::size_t v = 0; v < valence_.size(); ++v)
      if (valence_[v] > 0 && !fixed_[v]) {
        ++used;
        six += valence_[v] == 6;
      }
    v6 = used ? double(six) / double(used) : 0;
  }

  Mesh& m_;
  const Sheets& sh_;
  const bool single_;  // one closed surface (else: interfaces between materials)
  SurfaceImproveParams p_;
  double cos_fold_;
  double mean_edge_ = 1, tol_ = 0;
  std::vector<int> opp_;
  std::vector<double> rr_face_;  // flip_pass' filter
  EdgeSet edges_;
  std::vector<std::pair<std::uint64_t, int>> halves_;  // build_opposites' scratch
  std::vector<int> valence_;
  std::vector<char> fixed_;  // junction vertices (several sheets, or an edge with != 2 faces)
  std::vector<std::array<int, 2>> curve_nb_;  // the other ends of a vertex's first two junction edges
  std::vector<int> curve_count_;              // junction edges at each vertex
  const std::vector<char>& frozen_;
  SurfaceImproveStats st_;
};


// Intersecting face pairs of `m` (indices into m.faces). One surface: the
// mesh itself. Interfaces: each material's closed surface in turn
// (pm::material_self_intersections; a material whose surface is not a
// manifold polygon mesh is skipped).
// `flipped_from_checked`: m came from a checked polygon mesh by edge flips
// (never onto an existing edge) and vertex moves, which keep every vertex's
// link one cycle, so it is one too.
std::vector<std::pair<int, int>> crossings(const Mesh& m, const std::vector<int>* materials,
                                           bool flipped_from_checked) {
  if (materials) return material_self_intersections(m, *materials);
  std::vector<std::pair<int, int>> pairs;
  if (!self_intersecting_faces(m, pairs, flipped_from_checked))
    throw InputError("improve_surface: the improved mesh is not a manifold polygon mesh (internal error)");
  return pairs;
}

// Flips and moves are local tests; where two sheets of the surface are
// closer than an edge (thin parts), they can still make triangles cross.
// Check with CGAL, switch off flips (then moves) around every new crossing
// (and the 1-rings), and redo from the original mesh; a few rounds suffice.
SurfaceImproveStats improve_guarded(Mesh& mesh, const Sheets& sh, bool single, const std::vector<int>* materials,
                                    const SurfaceImproveParams& p) {
  const Mesh original = mesh;
  const bool checked = single && closed_oriented_manifold(original);
  const std::size_t before = p.input_embedded ? 0 : crossings(original, materials, checked).size();
  std::vector<char> frozen(mesh.vertices.size(), 0);
  SurfaceImproveStats st;
  for (int attempt = 0;; ++attempt) {
    Improver im(mesh, sh, single, p, frozen);
    st = im.run();
    const auto pairs = crossings(mesh, materials, checked);
    st.self_intersections = pairs.size();
    if (pairs.size() <= before || attempt == 4) break;
    std::vector<char> seed(mesh.vertices.size(), 0);
    for (const auto& fp : pairs)
      for (int f : {fp.first, fp.second})
        for (int v : mesh.faces[std::size_t(f)]) seed[std::size_t(v)] = 1;
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

void check_params(const SurfaceImproveParams& p) {
  if (p.rounds < 0 || p.smoothing_steps < 0 || !(p.smoothing >= 0 && p.smoothing <= 1))
    throw UsageError("improve_surface: rounds and smoothing steps must be >= 0 and smoothing in [0, 1]");
}

}  // namespace

SurfaceImproveStats improve_surface(Mesh& mesh, const ScalarField& field, double iso, const SurfaceImproveParams& p) {
  mesh.validate("improve_surface");
  check_params(p);
  Sheets sh;
  sh.group.assign(mesh.faces.size(), 0);
  sh.eval = [&](const Vec3& x, int, Vec3& g) { return field.value_gradient(x, g) - iso; };
  return improve_guarded(mesh, sh, true, nullptr, p);
}

SurfaceImproveStats improve_interfaces(Mesh& mesh, const MaterialSet& ms, const SurfaceImproveParams& p) {
  mesh.validate("improve_interfaces");
  check_params(p);
  const auto ia = mesh.face_ints.find("label_a"), ib = mesh.face_ints.find("label_b");
  if (ia == mesh.face_ints.end() || ib == mesh.face_ints.end())
    throw InputError("improve_interfaces: the mesh has no label_a/label_b face properties; expected an interface mesh");
  // One sheet per material pair: f_a - f_b = d_b - d_a = 0 (d negative inside).
  std::map<std::pair<int, int>, int> pair_index;
  std::vector<std::pair<std::size_t, std::size_t>> pair_fields;
  Sheets sh;
  sh.group.resize(mesh.faces.size());
  std::vector<int> materials;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const int a = ia->second[f], b = ib->second[f];
    const std::size_t xa = ms.index_of(a), xb = ms.index_of(b);
    if (xa >= ms.size() || xb >= ms.size())
      throw InputError("improve_interfaces: face " + std::to_string(f) + " joins labels " + std::to_string(a) +
                       " and " + std::to_string(b) + ", not both in the material set");
    const auto it = pair_index.emplace(std::make_pair(a, b), int(pair_fields.size())).first;
    if (it->second == int(pair_fields.size())) pair_fields.emplace_back(xa, xb);
    sh.group[f] = it->second;
    materials.push_back(a);
    materials.push_back(b);
  }
  std::sort(materials.begin(), materials.end());
  materials.erase(std::unique(materials.begin(), materials.end()), materials.end());
  sh.face_labels.resize(mesh.faces.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) sh.face_labels[f] = {ia->second[f], ib->second[f]};
  CellProjectParams cp;
  cp.max_steps = p.newton_steps + 4;
  sh.project_curve = [&](Vec3& x, const std::array<int, 3>& labels) {
    const JunctionCell c = make_cell({int(ms.index_of(labels[0])), int(ms.index_of(labels[1])),
                                      int(ms.index_of(labels[2]))});
    const CellProjection r = project_to_cell(ms, c, x, cp);
    if (!r.converged || !r.dominant) return false;
    x = r.x;
    return true;
  };
  sh.eval = [&](const Vec3& x, int g, Vec3& grad) {
    const auto [xa, xb] = pair_fields[std::size_t(g)];
    Vec3 ga, gb;
    const double da = ms.fields[xa]->value_gradient(x, ga), db = ms.fields[xb]->value_gradient(x, gb);
    grad = gb - ga;
    return db - da;
  };
  return improve_guarded(mesh, sh, false, &materials, p);
}

}  // namespace pm
