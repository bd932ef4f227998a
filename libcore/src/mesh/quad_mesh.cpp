#include "pm/mesh/quad_mesh.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>

#include "pm/base/error.h"

namespace pm {
namespace {

constexpr double kRadToDeg = 57.29577951308232;

Vec3 triangle_normal(const Mesh& m, const std::array<int, 3>& f) {
  const Vec3 &a = m.vertices[std::size_t(f[0])], &b = m.vertices[std::size_t(f[1])], &c = m.vertices[std::size_t(f[2])];
  return cross(b - a, c - a);
}

// The quad of triangles t and u across their shared edge, in the triangles'
// orientation: t = (a, b, c) with the edge a -> b, u with b -> a and the
// opposite vertex d gives (a, d, b, c).
bool merged(const std::array<int, 3>& t, const std::array<int, 3>& u, std::array<int, 4>& q) {
  for (int i = 0; i < 3; ++i) {
    const int a = t[std::size_t(i)], b = t[std::size_t((i + 1) % 3)], c = t[std::size_t((i + 2) % 3)];
    for (int j = 0; j < 3; ++j)
      if (u[std::size_t(j)] == b && u[std::size_t((j + 1) % 3)] == a) {
        const int d = u[std::size_t((j + 2) % 3)];
        if (d == c) return false;
        q = {a, d, b, c};
        return true;
      }
  }
  return false;
}

// Largest deviation of a quad's corner angles from 90°.
double corner_deviation(const std::vector<Vec3>& x, const std::array<int, 4>& q) {
  double worst = 0;
  for (int i = 0; i < 4; ++i) {
    const double a = corner_angle_deg(x[std::size_t(q[std::size_t((i + 3) % 4)])], x[std::size_t(q[std::size_t(i)])],
                                  x[std::size_t(q[std::size_t((i + 1) % 4)])]);
    worst = std::max(worst, std::fabs(a - 90));
  }
  return worst;
}

struct Candidate {
  double score;  // corner deviation, smaller is better
  std::uint32_t t, u;
  bool operator<(const Candidate& o) const {
    return score != o.score ? score < o.score : (t != o.t ? t < o.t : u < o.u);
  }
};

// Augmenting paths (as in maximum matching) of at most `depth` matched
// pairs from every triangle left alone: t0 - t1 = t2 - t3 = ... - tk, where
// "-" is a candidate quad not taken, "=" a quad taken and tk is also alone;
// flipping the path makes one more quad out of the same candidates (every
// quad still passes the corner and fold tests, and only candidates with
// corners within `max_deviation` of 90° are used). Depth-first, candidates in
// the greedy's order (best quad first), triangles in index order:
// deterministic. Returns the number of augmentations.
std::size_t augment(const std::vector<Candidate>& like, const std::vector<Candidate>& other, std::size_t nf,
                    int depth, double max_deviation, std::vector<int>& partner) {
  // Candidate partners of each triangle, best first (the lists are sorted).
  std::vector<std::uint32_t> start(nf + 1, 0), adj;
  for (const auto* list : {&like, &other})
    for (const Candidate& c : *list) {
      if (c.score > max_deviation) continue;
      ++start[c.t + 1];
      ++start[c.u + 1];
    }
  for (std::size_t f = 0; f < nf; ++f) start[f + 1] += start[f];
  adj.resize(start[nf]);
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (const auto* list : {&like, &other})
    for (const Candidate& c : *list) {
      if (c.score > max_deviation) continue;
      adj[fill[c.t]++] = c.u;
      adj[fill[c.u]++] = c.t;
    }
  std::vector<std::uint32_t> seen(nf, 0), path;
  std::uint32_t stamp = 0;
  // From free or re-paired triangle a: find b among a's candidates that is
  // alone (done), or matched to c from which the search goes on.
  std::function<bool(std::uint32_t, int)> search = [&](std::uint32_t a, int left) -> bool {
    for (std::uint32_t k = start[a]; k < start[a + 1]; ++k) {
      const std::uint32_t b = adj[k];
      if (seen[b] == stamp || int(b) == partner[a]) continue;
      seen[b] = stamp;
      if (partner[b] < 0) {
        path.push_back(a);
        path.push_back(b);
        return true;
      }
      if (left == 0) continue;
      const std::uint32_t c = std::uint32_t(partner[b]);
      if (seen[c] == stamp) continue;
      seen[c] = stamp;
      if (search(c, left - 1)) {
        path.push_back(a);
        path.push_back(b);
        return true;
      }
    }
    return false;
  };
  std::size_t count = 0;
  for (std::uint32_t t = 0; t < nf; ++t) {
    if (partner[t] >= 0 || start[t] == start[t + 1]) continue;
    ++stamp;
    seen[t] = stamp;
    path.clear();
    if (!search(t, depth)) continue;
    // path holds pairs (a, b) to match, innermost first.
    for (std::size_t i = 0; i + 1 < path.size(); i += 2) {
      partner[path[i]] = int(path[i + 1]);
      partner[path[i + 1]] = int(path[i]);
    }
    ++count;
  }
  return count;
}

}  // namespace

QuadResult quad_dominant(const Mesh& tri, const std::vector<int>& type, const QuadParams& p) {
  tri.validate("quad_dominant");
  if (type.size() != tri.vertices.size())
    throw InputError("quad_dominant: " + std::to_string(type.size()) + " vertex types for " +
                     std::to_string(tri.vertices.size()) + " vertices; expected one type per vertex");
  const std::size_t nf = tri.faces.size();
  // Edges with their triangles, matched by sorting.
  struct Half {
    std::uint64_t key;
    std::uint32_t face;
    bool operator<(const Half& o) const { return key != o.key ? key < o.key : face < o.face; }
  };
  std::vector<Half> halves;
  halves.reserve(3 * nf);
  for (std::size_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k)
      halves.push_back({undirected_edge_key(tri.faces[f][std::size_t(k)], tri.faces[f][std::size_t((k + 1) % 3)]),
                        std::uint32_t(f)});
  std::sort(halves.begin(), halves.end());
  QuadResult r;
  std::vector<Candidate> like, other;
  const double cos_fold = std::cos(p.max_fold / kRadToDeg);
  for (std::size_t i = 0; i < halves.size();) {
    std::size_t j = i + 1;
    while (j < halves.size() && halves[j].key == halves[i].key) ++j;
    if (j - i > 2) {
      const std::uint64_t k = halves[i].key;
      throw InputError("quad_dominant: edge (" + std::to_string(k >> 32) + ", " + std::to_string(k & 0xffffffffu) +
                       ") is in " + std::to_string(j - i) + " triangles; expected a manifold mesh (at most 2)");
    }
    if (j - i == 2) {
      const std::uint32_t t = halves[i].face, u = halves[i + 1].face;
      const int a = int(halves[i].key >> 32), b = int(halves[i].key & 0xffffffffu);
      const bool is_like = type[std::size_t(a)] == type[std::size_t(b)];
      r.like_edges += is_like;
      std::array<int, 4> q;
      if (merged(tri.faces[t], tri.faces[u], q)) {
        const Vec3 nt = triangle_normal(tri, tri.faces[t]), nu = triangle_normal(tri, tri.faces[u]);
        const double ln = norm(nt) * norm(nu);
        const double dev = corner_deviation(tri.vertices, q);
        if (ln > 0 && dot(nt, nu) >= cos_fold * ln && dev <= p.max_corner_deviation)
          (is_like ? like : other).push_back({dev, t, u});
      }
    }
    i = j;
  }
  // Greedy matching, best quad first: like edges (the checkerboard's
  // diagonals), then the leftovers across any edge.
  std::vector<int> partner(nf, -1);
  auto take = [&](std::vector<Candidate>& c, std::size_t& count) {
    std::sort(c.begin(), c.end());
    for (const Candidate& k : c)
      if (partner[k.t] < 0 && partner[k.u] < 0) {
        partner[k.t] = int(k.u);
        partner[k.u] = int(k.t);
        ++count;
      }
  };
  take(like, r.like_merges);
  if (p.pair_leftovers) take(other, r.leftover_merges);
  if (p.pair_leftovers && p.augment_depth > 0) {
    r.augmented = augment(like, other, nf, p.augment_depth, p.augment_max_deviation, partner);
    if (r.augmented > 0) r.like_merges = r.leftover_merges = 0;  // counted again below: paths re-pair quads
  }
  r.mesh.vertices = tri.vertices;
  r.mesh.faces.reserve(nf);
  for (std::size_t f = 0; f < nf; ++f) {
    const auto& t = tri.faces[f];
    if (partner[f] < 0) {
      r.mesh.faces.push_back({t[0], t[1], t[2], -1});
      ++r.triangles_left;
    } else if (std::size_t(partner[f]) > f) {
      std::array<int, 4> q;
      merged(t, tri.faces[std::size_t(partner[f])], q);
      r.mesh.faces.push_back(q);
      // q = (a, d, b, c): the two triangles shared the edge a-b.
      if (r.augmented > 0) ++(type[std::size_t(q[0])] == type[std::size_t(q[2])] ? r.like_merges : r.leftover_merges);
    }
  }
  return r;
}

double corner_angle_deg(const Vec3& prev, const Vec3& v, const Vec3& next) {
  const Vec3 a = prev - v, b = next - v;
  const double la = norm(a), lb = norm(b);
  if (!(la > 0 && lb > 0)) return 0;
  return std::acos(std::clamp(dot(a, b) / (la * lb), -1.0, 1.0)) * kRadToDeg;
}

Vec3 polygon_normal(const std::vector<Vec3>& x, const std::array<int, 4>& f) {
  const int n = f[3] >= 0 ? 4 : 3;
  Vec3 s(0, 0, 0);
  for (int k = 0; k < n; ++k) {
    const Vec3& p = x[std::size_t(f[std::size_t(k)])];
    s += cross(x[std::size_t(f[std::size_t((k + 1) % n)])] - p, x[std::size_t(f[std::size_t((k + n - 1) % n)])] - p);
  }
  return s;
}

double polygon_scaled_jacobian(const std::vector<Vec3>& x, const std::array<int, 4>& f) {
  if (f[3] < 0) return 1;
  const Vec3 normal = polygon_normal(x, f);
  const double ln = norm(normal);
  double jac = 1;
  for (int k = 0; k < 4; ++k) {
    const Vec3& p = x[std::size_t(f[std::size_t(k)])];
    const Vec3 e1 = x[std::size_t(f[std::size_t((k + 1) % 4)])] - p;
    const Vec3 e2 = x[std::size_t(f[std::size_t((k + 3) % 4)])] - p;
    const double l = norm(e1) * norm(e2);
    jac = std::min(jac, l > 0 && ln > 0 ? dot(cross(e1, e2), normal) / (l * ln) : -1.0);
  }
  return jac;
}

std::uint64_t undirected_edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
}

QuadQuality quad_quality(const PolyMesh& m) {
  m.validate("quad_quality");
  QuadQuality q;
  q.faces = m.faces.size();
  std::vector<std::uint64_t> edges;
  edges.reserve(4 * m.faces.size());
  double jac_sum = 0;
  for (const auto& f : m.faces) {
    const int n = f[3] >= 0 ? 4 : 3;
    for (int k = 0; k < n; ++k)
      edges.push_back(undirected_edge_key(f[std::size_t(k)], f[std::size_t((k + 1) % n)]));
    if (n == 3) {
      ++q.triangles;
      continue;
    }
    ++q.quads;
    const Vec3* x[4];
    for (int k = 0; k < 4; ++k) x[k] = &m.vertices[std::size_t(f[std::size_t(k)])];
    for (int k = 0; k < 4; ++k) {
      const double a = corner_angle_deg(*x[(k + 3) % 4], *x[k], *x[(k + 1) % 4]);
      q.corner_min = std::min(q.corner_min, a);
      q.corner_max = std::max(q.corner_max, a);
      ++q.corner_hist[std::size_t(std::clamp(int(a / 10), 0, 17))];
      ++q.corners;
      q.corners_70_110 += a >= 70 && a <= 110;
    }
    const double jac = polygon_scaled_jacobian(m.vertices, f);
    q.jacobian_min = std::min(q.jacobian_min, jac);
    jac_sum += jac;
  }
  q.jacobian_mean = q.quads ? jac_sum / double(q.quads) : 0.0;
  if (!q.quads) q.corner_min = 0;
  std::sort(edges.begin(), edges.end());
  std::vector<int> valence(m.vertices.size(), 0);
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i + 1;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i == 1) ++q.boundary_edges;
    if (j - i > 2) ++q.nonmanifold_edges;
    ++valence[std::size_t(edges[i] >> 32)];
    ++valence[std::size_t(edges[i] & 0xffffffffu)];
    i = j;
  }
  for (int v : valence) {
    if (v == 0) continue;
    ++q.vertices;
    (v == 4 ? q.valence4 : q.irregular) += 1;
  }
  return q;
}

Json to_json(const QuadQuality& q) {
  Json h = Json::array();
  for (auto c : q.corner_hist) h.push_back(c);
  return {{"vertices", q.vertices},
          {"faces", q.faces},
          {"quads", q.quads},
          {"triangles", q.triangles},
          {"quad_share", q.quad_share()},
          {"corner_min", q.corner_min},
          {"corner_max", q.corner_max},
          {"corner_hist_10deg", h},
          {"corner_share_70_110", q.corner_share_70_110()},
          {"jacobian_min", q.quads ? q.jacobian_min : 0.0},
          {"jacobian_mean", q.jacobian_mean},
          {"valence4_share", q.valence4_share()},
          {"irregular_vertices", q.irregular},
          {"boundary_edges", q.boundary_edges},
          {"nonmanifold_edges", q.nonmanifold_edges},
          {"watertight", q.boundary_edges == 0 && q.nonmanifold_edges == 0}};
}

}  // namespace pm
