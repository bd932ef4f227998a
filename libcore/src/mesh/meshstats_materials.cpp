#include "pm/mesh/meshstats_materials.h"

#include <algorithm>
#include <map>
#include <set>
#include <sstream>

#include "pm/base/error.h"
#include "pm/base/parallel.h"

namespace pm {

bool is_interface_mesh(const Mesh& m) {
  return m.face_ints.count("label_a") > 0 && m.face_ints.count("label_b") > 0;
}

Mesh material_from_interfaces(const Mesh& m, int label) {
  const auto& a = m.face_ints.at("label_a");
  const auto& b = m.face_ints.at("label_b");
  const auto index = m.vertex_scalars.find("index");
  Mesh out;
  std::vector<int> remap(m.vertices.size(), -1);
  auto vid = [&](int v) {
    if (remap[v] < 0) {
      remap[v] = int(out.vertices.size());
      out.vertices.push_back(m.vertices[v]);
      if (m.has_normals()) out.normals.push_back(m.normals[v]);
      for (const auto& [name, vals] : m.vertex_scalars)
        if (name != "index") out.vertex_scalars[name].push_back(vals[std::size_t(v)]);
      out.vertex_scalars["index"].push_back(index != m.vertex_scalars.end() ? index->second[std::size_t(v)]
                                                                            : double(v));
    }
    return remap[v];
  };
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    if (a[f] == b[f]) continue;
    const auto& t = m.faces[f];
    if (a[f] == label) out.faces.push_back({vid(t[0]), vid(t[1]), vid(t[2])});       // normal a -> b: outward
    else if (b[f] == label) out.faces.push_back({vid(t[0]), vid(t[2]), vid(t[1])});  // flipped
    else continue;
    for (const auto& [name, vals] : m.face_ints) out.face_ints[name].push_back(vals[f]);
  }
  return out;
}

InterfaceQuality interface_quality(const Mesh& m, const MeshQualityParams& p) {
  if (!is_interface_mesh(m))
    throw InputError("interface_quality: the mesh has no face properties label_a and label_b; expected an "
                     "interface mesh (tetlabel --materials)");
  m.validate("interface_quality");
  InterfaceQuality q;
  const auto& a = m.face_ints.at("label_a");
  const auto& b = m.face_ints.at("label_b");
  MeshQualityParams po = p;
  po.self_intersections = false;
  q.overall = mesh_quality(m, po);

  std::set<std::pair<int, int>> pairs;
  std::set<int> labels;
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    if (a[f] == b[f]) ++q.self_faces;
    pairs.emplace(std::min(a[f], b[f]), std::max(a[f], b[f]));
    labels.insert(a[f]);
    labels.insert(b[f]);
  }
  q.pairs.assign(pairs.begin(), pairs.end());
  {
    std::map<std::pair<int, int>, std::vector<int>> pair_faces;
    for (std::size_t f = 0; f < m.faces.size(); ++f)
      pair_faces[{std::min(a[f], b[f]), std::max(a[f], b[f])}].push_back(int(f));
    CreaseCount pooled;
    for (const auto& [pr, fs] : pair_faces) {
      const CreaseCount c = count_creases(m, fs);
      q.pair_creases[pr] = c;
      pooled.interior_edges += c.interior_edges;
      pooled.creased += c.creased;
    }
    q.overall.interior_edges = pooled.interior_edges;
    q.overall.creased_edges_20 = pooled.creased;
    q.overall.crease_share_20 = pooled.share();
  }

  // Edges -> incident faces: (edge key, face) sorted by key, one group per
  // edge (the counts below do not depend on the order within a group).
  std::vector<std::pair<std::uint64_t, int>> ef;
  ef.reserve(m.faces.size() * 3);
  for (std::size_t f = 0; f < m.faces.size(); ++f)
    for (int e = 0; e < 3; ++e) {
      std::uint64_t u = std::uint32_t(m.faces[f][e]), v = std::uint32_t(m.faces[f][(e + 1) % 3]);
      if (u > v) std::swap(u, v);
      ef.emplace_back((u << 32) | v, int(f));
    }
  std::sort(ef.begin(), ef.end());
  const auto junction = m.vertex_scalars.find("junction");
  std::size_t jv = 0, jv_ok = 0;
  std::map<int, int> sides;  // material -> faces of the edge bounding it
  for (std::size_t g = 0; g < ef.size();) {
    const std::uint64_t key = ef[g].first;
    std::size_t e = g;
    while (e < ef.size() && ef[e].first == key) ++e;
    const std::size_t nf = e - g;
    ++q.edges;
    if (nf == 1) {
      ++q.boundary_edges;
      ++q.bad_edges;
      g = e;
      continue;
    }
    sides.clear();
    for (std::size_t i = g; i < e; ++i) {
      const int f = ef[i].second;
      if (a[f] == b[f]) continue;
      ++sides[a[f]];
      ++sides[b[f]];
    }
    bool ok = true;
    for (const auto& [l, n] : sides)
      if (n != 2) ok = false;
    if (!ok) ++q.bad_edges;
    if (nf >= 3 && sides.size() >= 3) {
      ++q.junction_edges;
      if (junction != m.vertex_scalars.end()) {
        for (std::uint64_t v : {key >> 32, key & 0xffffffffu}) {
          ++jv;
          jv_ok += junction->second[std::size_t(v)] >= 3;
        }
      }
    }
    g = e;
  }
  if (jv > 0) q.junction_vertex_share = double(jv_ok) / double(jv);
  // Each material's closed surface on its own, side by side (each report
  // lands in its label's slot: the same for any schedule).
  const std::vector<int> ls(labels.begin(), labels.end());
  std::vector<MeshQuality> per(ls.size());
  pm::parallel_for(std::size_t(0), ls.size(),
                   [&](std::size_t i) { per[i] = mesh_quality(material_from_interfaces(m, ls[i]), p); });
  for (std::size_t i = 0; i < ls.size(); ++i) q.materials.emplace(ls[i], std::move(per[i]));
  return q;
}

Json to_json(const InterfaceQuality& q) {
  Json j;
  j["overall"] = to_json(q.overall);
  bool closed = true, manifold = true, self_free = true;
  double rr_min = q.overall.rr_min, rr_mean_min = q.overall.rr_mean;
  for (const auto& [l, mq] : q.materials) {
    closed = closed && mq.topology.boundary_edges == 0;
    manifold = manifold && mq.topology.nonmanifold_edges == 0 && mq.topology.nonmanifold_vertices == 0;
    self_free = self_free && mq.self_intersecting_pairs == 0;
    rr_min = std::min(rr_min, mq.rr_min);
    rr_mean_min = std::min(rr_mean_min, mq.rr_mean);
  }
  Json pairs = Json::array();
  for (const auto& [x, y] : q.pairs) pairs.push_back({x, y});
  j["interfaces"] = {{"edges", q.edges},
                     {"boundary_edges", q.boundary_edges},
                     {"junction_edges", q.junction_edges},
                     {"bad_edges", q.bad_edges},
                     {"self_faces", q.self_faces},
                     {"watertight", q.boundary_edges == 0},
                     {"labels_consistent", q.self_faces == 0},
                     {"materials_closed", closed},
                     {"materials_manifold", manifold},
                     {"materials_self_intersection_free", self_free},
                     {"rr_min_over_materials", rr_min},
                     {"rr_mean_lowest_material", rr_mean_min},
                     {"pairs", pairs}};
  Json per_pair = Json::array();
  for (const auto& [pr, c] : q.pair_creases)
    per_pair.push_back({{"pair", {pr.first, pr.second}}, {"interior_edges", c.interior_edges},
                        {"creased_edges", c.creased}, {"crease_share_20", c.share()}});
  j["interfaces"]["crease_share_20"] = q.overall.crease_share_20;
  j["interfaces"]["per_pair"] = per_pair;
  if (q.junction_vertex_share >= 0) j["interfaces"]["junction_edge_vertices_on_junctions"] = q.junction_vertex_share;
  Json mats = Json::object();
  for (const auto& [l, mq] : q.materials) mats[std::to_string(l)] = to_json(mq);
  j["materials"] = mats;
  return j;
}

std::vector<std::string> check_interface_requirements(const InterfaceQuality& q, const std::string& req) {
  std::vector<std::string> failed;
  std::stringstream ss(req);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item.erase(std::remove_if(item.begin(), item.end(), ::isspace), item.end());
    if (item.empty()) continue;
    auto fail_materials = [&](const std::string& what, auto bad) {
      std::string which;
      for (const auto& [l, mq] : q.materials)
        if (bad(mq)) which += (which.empty() ? "" : " ") + std::to_string(l);
      if (!which.empty()) failed.push_back(item + " (" + what + " of material(s) " + which + ")");
      return which.empty();
    };
    if (item == "watertight") {
      if (q.boundary_edges > 0) failed.push_back(item + " (" + std::to_string(q.boundary_edges) + " boundary edges)");
      fail_materials("open surface", [](const MeshQuality& mq) { return mq.topology.boundary_edges > 0; });
    } else if (item == "manifold") {
      if (q.bad_edges > 0)
        failed.push_back(item + " (" + std::to_string(q.bad_edges) + " edges not closing every material)");
      fail_materials("non-manifold surface", [](const MeshQuality& mq) {
        return mq.topology.nonmanifold_edges > 0 || mq.topology.nonmanifold_vertices > 0;
      });
    } else if (item == "no_self_intersections") {
      fail_materials("self-intersecting or untested surface",
                     [](const MeshQuality& mq) { return mq.self_intersecting_pairs != 0; });
    } else if (item == "labels_consistent") {
      if (q.self_faces > 0)
        failed.push_back(item + " (" + std::to_string(q.self_faces) + " faces separate a label from itself)");
    } else {
      for (auto& f : check_requirements(q.overall, item)) failed.push_back("overall " + f);
      const std::string key = item.substr(0, item.find_first_of("<>="));
      if (key == "rr_min" || key == "rr_mean" || key == "min_angle")
        for (const auto& [l, mq] : q.materials)
          for (auto& f : check_requirements(mq, item)) failed.push_back("material " + std::to_string(l) + " " + f);
    }
  }
  return failed;
}

}  // namespace pm
