#include "pm/baseline/lattice_iso.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>
#include <vector>

#include "pm/base/error.h"

namespace pm {
namespace {

// The 6 Kuhn tetrahedra of the unit cube: 0 -> e_a -> e_a + e_b -> (1,1,1).
constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};

struct Lattice {
  std::vector<std::array<int, 3>> pts;  // integer lattice coordinates (i, j, k)
  std::vector<std::array<int, 4>> tets; // indices into pts
};

// Lattice of n points per edge for a hexahedron or a tetrahedron.
Lattice make_lattice(NektarShape shape, int n) {
  Lattice L;
  const int m = n - 1;
  if (shape == NektarShape::Hexahedron) {
    auto id = [n](int i, int j, int k) { return i + n * (j + n * k); };
    for (int k = 0; k < n; ++k)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) L.pts.push_back({i, j, k});
    for (int k = 0; k < m; ++k)
      for (int j = 0; j < m; ++j)
        for (int i = 0; i < m; ++i)
          for (const auto& p : kPerm) {
            std::array<int, 3> c{i, j, k};
            std::array<int, 4> t;
            t[0] = id(c[0], c[1], c[2]);
            for (int s = 0; s < 3; ++s) {
              ++c[p[s]];
              t[s + 1] = id(c[0], c[1], c[2]);
            }
            L.tets.push_back(t);
          }
    return L;
  }
  // Tetrahedron: (i, j, k) with i + j + k <= m. In staircase coordinates
  // u = (i, i + j, i + j + k) it is 0 <= u0 <= u1 <= u2 <= m, a Kuhn simplex
  // of the big cube, which the Kuhn tetrahedra of the small cubes tile.
  std::vector<int> index(static_cast<std::size_t>(n) * n * n, -1);
  auto uid = [n](int a, int b, int c) { return a + n * (b + n * c); };
  for (int u2 = 0; u2 < n; ++u2)
    for (int u1 = 0; u1 <= u2; ++u1)
      for (int u0 = 0; u0 <= u1; ++u0) {
        index[uid(u0, u1, u2)] = static_cast<int>(L.pts.size());
        L.pts.push_back({u0, u1 - u0, u2 - u1});
      }
  for (int c2 = 0; c2 < m; ++c2)
    for (int c1 = 0; c1 < m; ++c1)
      for (int c0 = 0; c0 < m; ++c0)
        for (const auto& p : kPerm) {
          std::array<int, 3> c{c0, c1, c2};
          std::array<int, 4> t;
          bool ok = true;
          for (int s = 0; s < 4 && ok; ++s) {
            if (s > 0) ++c[p[s - 1]];
            const int v = index[uid(c[0], c[1], c[2])];
            ok = c[0] <= c[1] && c[1] <= c[2] && v >= 0;
            t[s] = v;
          }
          if (ok) L.tets.push_back(t);
        }
  return L;
}

struct Welder {
  bool on;
  double quantum;
  Mesh* mesh;
  std::vector<double>* elem;
  std::unordered_map<long long, std::vector<int>> buckets{};

  static long long key(long long x, long long y, long long z) {
    return (x * 73856093LL) ^ (y * 19349663LL) ^ (z * 83492791LL);
  }
  int add(const Vec3& p, int element_id) {
    // Cells of 1e3 quanta; a match is looked for in the 27 cells around p.
    const double q = quantum * 1e3;
    const long long cx = static_cast<long long>(std::floor(p.x / q)), cy = static_cast<long long>(std::floor(p.y / q)),
                    cz = static_cast<long long>(std::floor(p.z / q));
    if (on)
      for (long long dz = -1; dz <= 1; ++dz)
        for (long long dy = -1; dy <= 1; ++dy)
          for (long long dx = -1; dx <= 1; ++dx) {
            auto it = buckets.find(key(cx + dx, cy + dy, cz + dz));
            if (it == buckets.end()) continue;
            for (int v : it->second)
              if (norm(mesh->vertices[v] - p) <= quantum) return v;
          }
    const int v = static_cast<int>(mesh->vertices.size());
    mesh->vertices.push_back(p);
    elem->push_back(element_id);
    if (on) buckets[key(cx, cy, cz)].push_back(v);
    return v;
  }
};

}  // namespace

LatticeIsoResult lattice_isosurface(const HpField& field, double iso, const LatticeIsoParams& params) {
  if (params.points == 1 || params.points < 0)
    throw UsageError("lattice_isosurface: points = " + std::to_string(params.points) +
                     "; expected 0 (the default, modes + 1) or at least 2");
  LatticeIsoResult res;
  std::vector<double> elem_of_vertex;
  Welder weld{params.weld, 1e-12 * norm(field.domain().size()), &res.mesh, &elem_of_vertex};
  std::unordered_map<long long, Lattice> lattices;  // by (shape, n)
  for (int e = 0; e < field.num_elements(); ++e) {
    const auto m = field.modes(e);
    const int n = params.points > 0 ? params.points : std::max({m[0], m[1], m[2]}) + 1;
    const NektarShape shape = field.shape(e);
    const long long lkey = 2LL * n + (shape == NektarShape::Hexahedron ? 1 : 0);
    auto it = lattices.find(lkey);
    if (it == lattices.end()) it = lattices.emplace(lkey, make_lattice(shape, n)).first;
    const Lattice& L = it->second;
    std::vector<double> f(L.pts.size());
    std::vector<Vec3> x(L.pts.size());
    const double h = 2.0 / (n - 1);
    for (std::size_t i = 0; i < L.pts.size(); ++i) {
      const Vec3 xi{-1 + h * L.pts[i][0], -1 + h * L.pts[i][1], -1 + h * L.pts[i][2]};
      f[i] = field.ref_value(e, xi) - iso;
      x[i] = field.position(e, xi);
    }
    res.field_evaluations += L.pts.size();
    res.lattice_points += L.pts.size();
    res.lattice_tets += L.tets.size();
    // Vertex on lattice edge (a, b), welded per element by the edge.
    std::unordered_map<long long, int> edge_vertex;
    auto cut = [&](int a, int b) {
      if (a > b) std::swap(a, b);
      const long long key = static_cast<long long>(a) * static_cast<long long>(L.pts.size()) + b;
      auto ev = edge_vertex.find(key);
      if (ev != edge_vertex.end()) return ev->second;
      const double t = f[a] / (f[a] - f[b]);
      const int v = weld.add(x[a] + t * (x[b] - x[a]), field.element_id(e));
      edge_vertex.emplace(key, v);
      return v;
    };
    for (const auto& t : L.tets) {
      int pos[4], neg[4], np = 0, nn = 0;
      for (int s = 0; s < 4; ++s) (f[t[s]] > 0 ? pos[np++] : neg[nn++]) = t[s];
      if (np == 0 || nn == 0) continue;
      Vec3 cp, cn;
      for (int s = 0; s < np; ++s) cp += x[pos[s]] / np;
      for (int s = 0; s < nn; ++s) cn += x[neg[s]] / nn;
      const Vec3 up = cp - cn;
      auto emit = [&](int a, int b, int c) {
        if (a == b || b == c || a == c) return;
        const Vec3 nrm = cross(res.mesh.vertices[b] - res.mesh.vertices[a], res.mesh.vertices[c] - res.mesh.vertices[a]);
        if (dot(nrm, up) < 0) std::swap(b, c);
        res.mesh.faces.push_back({a, b, c});
      };
      if (np == 1 || nn == 1) {
        const int lone = np == 1 ? pos[0] : neg[0];
        const int* others = np == 1 ? neg : pos;
        emit(cut(lone, others[0]), cut(lone, others[1]), cut(lone, others[2]));
      } else {
        // Quad p0n0, p0n1, p1n1, p1n0.
        const int a = cut(pos[0], neg[0]), b = cut(pos[0], neg[1]), c = cut(pos[1], neg[1]), d = cut(pos[1], neg[0]);
        emit(a, b, c);
        emit(a, c, d);
      }
    }
  }
  res.mesh.vertex_scalars["element"] = std::move(elem_of_vertex);
  return res;
}

}  // namespace pm
