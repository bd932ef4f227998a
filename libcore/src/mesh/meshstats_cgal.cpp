// All CGAL includes for meshstats live here: they compile slowly.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <array>
#include <iterator>

#include "pm/mesh/meshstats.h"
#include "pm/mesh/topology.h"

namespace pm {

bool self_intersecting_faces(const Mesh& m, std::vector<std::pair<int, int>>& out, bool known_polygon_mesh) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using SM = CGAL::Surface_mesh<K::Point_3>;
  namespace PMP = CGAL::Polygon_mesh_processing;
  out.clear();
  std::vector<K::Point_3> pts;
  pts.reserve(m.vertices.size());
  for (const Vec3& v : m.vertices) pts.emplace_back(v.x, v.y, v.z);
  std::vector<std::array<std::size_t, 3>> polys;  // fixed-size polygons: no allocation per face
  polys.reserve(m.faces.size());
  for (const auto& f : m.faces) polys.push_back({std::size_t(f[0]), std::size_t(f[1]), std::size_t(f[2])});
  // CGAL's soup test costs more than the intersection test itself on a large
  // mesh; a closed, consistently oriented manifold passes it by construction.
  if (!known_polygon_mesh && !closed_oriented_manifold(m) && !PMP::is_polygon_soup_a_polygon_mesh(polys)) return false;
  SM sm;
  PMP::polygon_soup_to_polygon_mesh(pts, polys, sm);  // faces keep the soup's order
  std::vector<std::pair<SM::Face_index, SM::Face_index>> pairs;
  PMP::self_intersections<CGAL::Parallel_if_available_tag>(sm, std::back_inserter(pairs));
  // Found on several threads: sorted, each pair (lower, higher), so that the
  // list does not depend on the thread count.
  for (const auto& p : pairs) {
    const int a = int(std::size_t(p.first)), b = int(std::size_t(p.second));
    out.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(out.begin(), out.end());
  return true;
}

int count_self_intersections(const Mesh& m) {
  std::vector<std::pair<int, int>> pairs;
  if (!self_intersecting_faces(m, pairs)) return -1;
  return int(pairs.size());
}

std::vector<std::pair<int, int>> material_self_intersections(const Mesh& m, const std::vector<int>& materials,
                                                             std::vector<int>* untested) {
  std::vector<std::pair<int, int>> all, pairs;
  const auto& la = m.face_ints.at("label_a");
  const auto& lb = m.face_ints.at("label_b");
  for (int L : materials) {
    Mesh sub;
    sub.vertices = m.vertices;
    std::vector<int> back;
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
      if (la[f] == L) sub.faces.push_back(m.faces[f]);
      else if (lb[f] == L) sub.faces.push_back({m.faces[f][0], m.faces[f][2], m.faces[f][1]});
      else continue;
      back.push_back(int(f));
    }
    if (sub.faces.empty()) continue;
    if (!self_intersecting_faces(sub, pairs)) {
      if (untested) untested->push_back(L);
      continue;
    }
    for (const auto& [x, y] : pairs) all.emplace_back(back[std::size_t(x)], back[std::size_t(y)]);
  }
  std::sort(all.begin(), all.end());
  all.erase(std::unique(all.begin(), all.end()), all.end());
  return all;
}

}  // namespace pm
