#include "pm/mesh/topology.h"

#include <cstdint>
#include <numeric>
#include <unordered_map>
#include <utility>

namespace pm {
namespace {

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
}

}  // namespace

MeshTopology mesh_topology(const Mesh& m) {
  MeshTopology t;
  t.faces = m.faces.size();
  std::unordered_map<std::uint64_t, int> edges;
  edges.reserve(m.faces.size() * 2);
  std::vector<char> used(m.vertices.size(), 0);
  UnionFind uf(m.vertices.size());
  for (const auto& f : m.faces)
    for (int e = 0; e < 3; ++e) {
      ++edges[edge_key(f[e], f[(e + 1) % 3])];
      used[f[e]] = 1;
      uf.unite(f[e], f[(e + 1) % 3]);
    }
  t.edges = edges.size();
  for (const auto& [k, n] : edges) {
    (void)k;
    if (n == 1) ++t.boundary_edges;
    if (n > 2) ++t.nonmanifold_edges;
  }
  for (std::size_t v = 0; v < m.vertices.size(); ++v)
    if (used[v]) {
      ++t.vertices;
      if (uf.find(int(v)) == int(v)) ++t.components;
    }
  // Non-manifold vertices: the faces around a vertex form more than one fan.
  std::vector<std::vector<int>> vf(m.vertices.size());
  for (std::size_t i = 0; i < m.faces.size(); ++i)
    for (int v : m.faces[i]) vf[v].push_back(int(i));
  for (std::size_t v = 0; v < m.vertices.size(); ++v) {
    const auto& fs = vf[v];
    if (fs.size() < 2) continue;
    UnionFind local(fs.size());
    std::unordered_map<int, int> first;  // other vertex of an edge at v -> local face
    for (std::size_t a = 0; a < fs.size(); ++a)
      for (int w : m.faces[fs[a]])
        if (w != int(v)) {
          auto it = first.find(w);
          if (it == first.end()) first[w] = int(a);
          else local.unite(int(a), it->second);
        }
    std::size_t fans = 0;
    for (std::size_t a = 0; a < fs.size(); ++a) fans += local.find(int(a)) == int(a);
    if (fans > 1) ++t.nonmanifold_vertices;
  }
  t.euler = long(t.vertices) - long(t.edges) + long(t.faces);
  t.genus = t.closed_manifold() ? (2 * long(t.components) - t.euler) / 2 : -1;
  return t;
}

}  // namespace pm
