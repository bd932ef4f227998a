#include "pm/io/polygon_soup.h"

#include <climits>

#include "pm/base/error.h"

namespace pm {

Mesh mesh_from_polygons(std::vector<Vec3> points, const std::vector<std::vector<std::size_t>>& polygons,
                        const std::string& fn, const std::string& path, std::vector<int>* polygon_sizes) {
  if (points.size() > std::size_t(INT_MAX))
    throw InputError(fn + ": " + quote(path) + ": " + std::to_string(points.size()) +
                     " vertices; expected at most " + std::to_string(INT_MAX));
  Mesh m;
  m.vertices = std::move(points);
  const std::size_t nv = m.vertices.size();
  std::size_t ntri = 0;
  for (const auto& p : polygons) ntri += p.size() >= 3 ? p.size() - 2 : 0;
  m.faces.reserve(ntri);
  if (polygon_sizes) polygon_sizes->clear();
  for (std::size_t f = 0; f < polygons.size(); ++f) {
    const auto& p = polygons[f];
    if (p.size() < 3)
      throw InputError(fn + ": " + quote(path) + ": polygon " + std::to_string(f) + " has " +
                       std::to_string(p.size()) + " vertices; expected at least 3");
    for (std::size_t i : p)
      if (i >= nv)
        throw InputError(fn + ": " + quote(path) + ": polygon " + std::to_string(f) + " refers to vertex " +
                         std::to_string(i) + "; expected an index below " + std::to_string(nv) +
                         " (the vertex count)");
    for (std::size_t k = 1; k + 1 < p.size(); ++k) m.faces.push_back({int(p[0]), int(p[k]), int(p[k + 1])});
    if (polygon_sizes) polygon_sizes->push_back(int(p.size()));
  }
  return m;
}

}  // namespace pm
