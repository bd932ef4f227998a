#include "pm/mesh/tetlabel_materials.h"

#include <algorithm>
#include <cstdint>
#include <map>
#include <set>

#include "pm/base/error.h"
#include "pm/base/parallel.h"
#include "pm/mesh/tet_quality.h"

namespace pm {

int auto_outside_label(const MaterialSet& ms) {
  if (ms.size() == 0) throw Error("auto_outside_label: empty material set");
  const Box d = ms.domain();
  std::map<int, int> votes;
  for (int c = 0; c < 8; ++c) {
    const Vec3 p{(c & 1) ? d.hi.x : d.lo.x, (c & 2) ? d.hi.y : d.lo.y, (c & 4) ? d.hi.z : d.lo.z};
    ++votes[ms.label_at(p)];
  }
  int best = votes.begin()->first, n = 0;
  for (const auto& [l, v] : votes)
    if (v > n) {  // map order: ties keep the smallest label
      best = l;
      n = v;
    }
  return best;
}

namespace {

// Relabel the tetrahedra of `label` around each non-manifold edge and vertex
// of its surface to the most common other label among the tetrahedra there
// (ties: the smallest), which removes the pinch from its surface. Returns the
// number of tetrahedra changed.
std::size_t fill_pinches(TetMesh& tm, int label, int outside) {
  const Mesh m = material_surface(tm, label, outside);
  if (m.faces.empty()) return 0;
  const auto& idx = m.vertex_scalars.at("index");
  auto pid = [&](int v) { return int(idx[std::size_t(v)]); };
  const std::size_t nv = m.vertices.size();
  // Pinched edges: more than two faces, in (smaller, larger) vertex order.
  std::vector<std::uint64_t> edge_keys;
  edge_keys.reserve(3 * m.faces.size());
  // Link of every vertex (the opposite edge of each face at it), in face order.
  std::vector<std::uint32_t> link_start(nv + 1, 0);
  for (const auto& f : m.faces)
    for (int e = 0; e < 3; ++e) {
      const int a = f[e], b = f[(e + 1) % 3];
      edge_keys.push_back(std::uint64_t(std::min(a, b)) << 32 | std::uint32_t(std::max(a, b)));
      ++link_start[std::size_t(a) + 1];
    }
  std::sort(edge_keys.begin(), edge_keys.end());
  std::vector<std::vector<int>> sites;  // point ids whose common tetrahedra get relabelled
  for (std::size_t k = 0; k < edge_keys.size();) {
    std::size_t e = k + 1;
    while (e < edge_keys.size() && edge_keys[e] == edge_keys[k]) ++e;
    if (e - k > 2) sites.push_back({pid(int(edge_keys[k] >> 32)), pid(int(edge_keys[k] & 0xffffffffu))});
    k = e;
  }
  for (std::size_t v = 0; v < nv; ++v) link_start[v + 1] += link_start[v];
  std::vector<std::pair<int, int>> link(link_start[nv]);
  {
    std::vector<std::uint32_t> at(link_start.begin(), link_start.end() - 1);
    for (const auto& f : m.faces)
      for (int e = 0; e < 3; ++e) link[at[std::size_t(f[e])]++] = {f[(e + 1) % 3], f[(e + 2) % 3]};
  }
  // Pinched vertices: the link edges do not form one connected graph.
  std::vector<int> node, parent;  // the link's vertices; union-find over them
  for (std::size_t v = 0; v < nv; ++v) {
    const std::uint32_t b = link_start[v], e = link_start[v + 1];
    if (b == e) continue;
    node.clear();
    parent.clear();
    auto find = [&](int w) {
      std::size_t s = 0;
      while (s < node.size() && node[s] != w) ++s;
      if (s == node.size()) {
        node.push_back(w);
        parent.push_back(int(s));
      }
      int r = int(s);
      while (parent[std::size_t(r)] != r) r = parent[std::size_t(r)];
      return r;
    };
    for (std::uint32_t k = b; k < e; ++k) {
      const int ra = find(link[k].first), rb = find(link[k].second);
      if (ra != rb) parent[std::size_t(std::max(ra, rb))] = std::min(ra, rb);
    }
    std::size_t roots = 0;
    for (std::size_t s = 0; s < node.size(); ++s) roots += parent[s] == int(s);
    if (roots != 1) sites.push_back({pid(int(v))});
  }
  if (sites.empty()) return 0;
  const VertexTets vt(tm);
  std::size_t changed = 0;
  std::vector<int> around;
  for (const auto& site : sites) {
    around.clear();
    for (const int* it = vt.begin(site[0]); it != vt.end(site[0]); ++it) {
      const int t = *it;
      bool all = true;
      for (std::size_t i = 1; i < site.size(); ++i) {
        const auto& tv = tm.tets[std::size_t(t)];
        all = all && std::find(tv.begin(), tv.end(), site[i]) != tv.end();
      }
      if (all) around.push_back(t);
    }
    std::map<int, int> votes;
    for (int t : around)
      if (tm.labels[std::size_t(t)] != label) ++votes[tm.labels[std::size_t(t)]];
    if (votes.empty()) continue;
    int best = votes.begin()->first, bn = 0;
    for (const auto& [l, n] : votes)
      if (n > bn) {
        best = l;
        bn = n;
      }
    for (int t : around)
      if (tm.labels[std::size_t(t)] == label) {
        tm.labels[std::size_t(t)] = best;
        ++changed;
      }
  }
  return changed;
}

}  // namespace

std::size_t relabel_sliver_spikes(TetMesh& tm, int outside, double min_dihedral) {
  const std::size_t nt = tm.tets.size();
  std::vector<int> to(nt, 0);
  std::vector<char> spike(nt, 0);
  pm::parallel_for(std::size_t(0), nt, [&](std::size_t t) {
    int lab[4];
    for (int i = 0; i < 4; ++i) {
      const int n = tm.neighbours[t][std::size_t(i)];
      lab[i] = n >= 0 ? tm.labels[std::size_t(n)] : outside;
    }
    const int own = tm.labels[t];
    int own_count = 0, best = own, best_count = 0;
    for (int i = 0; i < 4; ++i) {
      own_count += lab[i] == own;
      if (lab[i] == own) continue;
      int c = 0;
      for (int j = 0; j < 4; ++j) c += lab[j] == lab[i];
      if (c > best_count || (c == best_count && lab[i] < best)) {
        best = lab[i];
        best_count = c;
      }
    }
    if (own_count > 1 || best_count < 2) return;
    const auto& v = tm.tets[t];
    const DihedralRange r = tet_dihedral_range(tm.points[std::size_t(v[0])], tm.points[std::size_t(v[1])],
                                               tm.points[std::size_t(v[2])], tm.points[std::size_t(v[3])]);
    if (!(r.min < min_dihedral)) return;
    spike[t] = 1;
    to[t] = best;
  });
  std::size_t changed = 0;
  for (std::size_t t = 0; t < nt; ++t)
    if (spike[t]) {
      tm.labels[t] = to[t];
      ++changed;
    }
  return changed;
}

MaterialMeshes mesh_materials(TetMesh& tm, const MaterialSet& ms, const MaterialMeshParams& p) {
  if (ms.size() == 0) throw Error("mesh_materials: empty material set");
  MaterialMeshes out;
  const Box dom = ms.domain();
  const int outside = p.outside_label;
  const MaterialBounds bounds = material_bounds(ms);
  out.label_stats = label_tets(
      tm, [&](const Vec3& x) { return dom.contains(x) ? ms.labels[argmax_bounded(ms, bounds, x)] : outside; },
      p.label);

  if (p.spike_dihedral > 0) out.spikes = relabel_sliver_spikes(tm, outside, p.spike_dihedral);

  auto present = [&] {
    std::set<int> s(tm.labels.begin(), tm.labels.end());
    s.erase(outside);
    return s;
  };
  if (p.repair) {
    for (int round = 0; round < p.repair_rounds; ++round) {
      std::size_t changed = 0;
      for (int l : present()) changed += make_manifold(tm, l, outside);
      // The outside material's surface (the union of the others') can still
      // pinch where two other materials meet it only along an edge or at a
      // vertex; and any material make_manifold could not fix: fill the pinch.
      std::set<int> all = present();
      all.insert(outside);
      for (int l : all) changed += fill_pinches(tm, l, outside);
      out.relabelled += changed;
      if (changed == 0) break;
    }
  }
  for (int l : tm.labels) ++out.tets_per_label[l];
  // The interface mesh and every material's surface (the outside's only for
  // its check) read the labelled tetrahedra side by side.
  const std::set<int> labels_present = present();
  std::vector<int> surface_label(labels_present.begin(), labels_present.end());
  surface_label.push_back(outside);
  std::vector<Mesh> surface(surface_label.size());
  std::vector<char> closed(surface_label.size(), 0);
  pm::parallel_tasks(surface_label.size() + 1, [&](std::size_t i) {
    if (i == surface_label.size()) {
      out.interfaces = interface_mesh(tm, outside);
      return;
    }
    surface[i] = material_surface(tm, surface_label[i], outside);
    closed[i] = mesh_topology(surface[i]).closed_manifold();
  });
  {
    const auto& a = out.interfaces.face_ints.at("label_a");
    const auto& b = out.interfaces.face_ints.at("label_b");
    std::set<std::pair<int, int>> s;
    for (std::size_t f = 0; f < a.size(); ++f) s.emplace(a[f], b[f]);
    out.pairs.assign(s.begin(), s.end());
    std::vector<int> pair(a.size());
    for (std::size_t f = 0; f < a.size(); ++f)
      pair[f] = int(std::lower_bound(out.pairs.begin(), out.pairs.end(), std::make_pair(a[f], b[f])) -
                    out.pairs.begin());
    out.interfaces.face_ints["pair"] = std::move(pair);
  }
  for (std::size_t i = 0; i < surface_label.size(); ++i) {
    if (!closed[i]) out.nonmanifold_materials.push_back(surface_label[i]);
    if (i + 1 < surface_label.size()) out.surfaces.emplace(surface_label[i], std::move(surface[i]));
  }
  return out;
}

}  // namespace pm
