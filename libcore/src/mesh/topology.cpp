#include "pm/mesh/topology.h"

#include <algorithm>
#include <cstdint>
#include <numeric>
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
  // Flat arrays only (sorted edge keys, vertex -> faces in CSR): surfaces of
  // a million triangles are checked several times per pipeline run.
  MeshTopology t;
  const std::size_t nf = m.faces.size(), nv = m.vertices.size();
  t.faces = nf;
  std::vector<std::uint64_t> keys;
  keys.reserve(3 * nf);
  std::vector<char> used(nv, 0);
  UnionFind uf(nv);
  for (const auto& f : m.faces)
    for (int e = 0; e < 3; ++e) {
      keys.push_back(edge_key(f[e], f[(e + 1) % 3]));
      used[f[e]] = 1;
      uf.unite(f[e], f[(e + 1) % 3]);
    }
  std::sort(keys.begin(), keys.end());
  for (std::size_t i = 0; i < keys.size();) {
    std::size_t j = i + 1;
    while (j < keys.size() && keys[j] == keys[i]) ++j;
    ++t.edges;
    if (j - i == 1) ++t.boundary_edges;
    if (j - i > 2) ++t.nonmanifold_edges;
    i = j;
  }
  std::vector<std::uint64_t>().swap(keys);
  for (std::size_t v = 0; v < nv; ++v)
    if (used[v]) {
      ++t.vertices;
      if (uf.find(int(v)) == int(v)) ++t.components;
    }
  // Non-manifold vertices: the faces around a vertex form more than one fan
  // (faces joined by an edge at the vertex, i.e. by a shared other vertex).
  std::vector<std::size_t> start(nv + 1, 0);
  for (const auto& f : m.faces)
    for (int v : f) ++start[std::size_t(v) + 1];
  for (std::size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<int> list(start[nv]);
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < nf; ++i)
      for (int v : m.faces[i]) list[fill[std::size_t(v)]++] = int(i);
  }
  std::vector<std::pair<int, int>> others;  // (other vertex of an edge at v, local face)
  UnionFind local(0);
  for (std::size_t v = 0; v < nv; ++v) {
    const std::size_t k = start[v + 1] - start[v];
    if (k < 2) continue;
    others.clear();
    for (std::size_t a = 0; a < k; ++a)
      for (int w : m.faces[std::size_t(list[start[v] + a])])
        if (w != int(v)) others.push_back({w, int(a)});
    std::sort(others.begin(), others.end());
    local.parent.resize(k);
    std::iota(local.parent.begin(), local.parent.end(), 0);
    for (std::size_t q = 1; q < others.size(); ++q)
      if (others[q].first == others[q - 1].first) local.unite(others[q].second, others[q - 1].second);
    std::size_t fans = 0;
    for (std::size_t a = 0; a < k; ++a) fans += local.find(int(a)) == int(a);
    if (fans > 1) ++t.nonmanifold_vertices;
  }
  t.euler = long(t.vertices) - long(t.edges) + long(t.faces);
  t.genus = t.closed_manifold() ? (2 * long(t.components) - t.euler) / 2 : -1;
  return t;
}

bool closed_oriented_manifold(const Mesh& m) {
  if (!mesh_topology(m).closed_manifold()) return false;
  std::vector<std::uint64_t> directed;
  directed.reserve(3 * m.faces.size());
  for (const auto& t : m.faces)
    for (int k = 0; k < 3; ++k)
      directed.push_back(std::uint64_t(std::uint32_t(t[k])) | (std::uint64_t(std::uint32_t(t[(k + 1) % 3])) << 32));
  std::sort(directed.begin(), directed.end());
  return std::adjacent_find(directed.begin(), directed.end()) == directed.end();
}

}  // namespace pm
