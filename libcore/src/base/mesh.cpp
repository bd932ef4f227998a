#include "pm/base/mesh.h"

#include <algorithm>

#include "pm/base/error.h"

namespace pm {

void Mesh::validate(const std::string& what) const {
  const std::size_t nv = vertices.size(), nf = faces.size();
  if (!normals.empty() && normals.size() != nv)
    throw InputError(what + ": " + std::to_string(normals.size()) + " normals for " + std::to_string(nv) +
                     " vertices; expected one normal per vertex or none");
  for (const auto& [name, values] : vertex_scalars)
    if (values.size() != nv)
      throw InputError(what + ": vertex property " + quote(name) + " has " + std::to_string(values.size()) +
                       " values; expected " + std::to_string(nv) + " (one per vertex)");
  for (const auto& [name, values] : face_ints)
    if (values.size() != nf)
      throw InputError(what + ": face property " + quote(name) + " has " + std::to_string(values.size()) +
                       " values; expected " + std::to_string(nf) + " (one per face)");
  for (std::size_t f = 0; f < nf; ++f)
    for (int c = 0; c < 3; ++c) {
      const int i = faces[f][c];
      if (i < 0 || std::size_t(i) >= nv)
        throw InputError(what + ": face " + std::to_string(f) + " refers to vertex " + std::to_string(i) +
                         "; expected an index in [0, " + std::to_string(nv) + ")");
    }
}

void compute_vertex_normals(Mesh& m) {
  const std::size_t nv = m.vertices.size();
  for (std::size_t f = 0; f < m.faces.size(); ++f)
    for (int i : m.faces[f])
      if (i < 0 || std::size_t(i) >= nv)
        throw InputError("compute_vertex_normals: face " + std::to_string(f) + " refers to vertex " +
                         std::to_string(i) + "; expected an index in [0, " + std::to_string(nv) + ")");
  std::vector<Vec3> n(m.vertices.size());
  for (const auto& f : m.faces) {
    // |cross| is twice the triangle area: an area-weighted sum.
    const Vec3 c = cross(m.vertices[f[1]] - m.vertices[f[0]], m.vertices[f[2]] - m.vertices[f[0]]);
    for (int k = 0; k < 3; ++k) n[f[k]] += c;
  }
  for (Vec3& v : n) v = normalized(v);
  m.normals = std::move(n);
}

std::size_t PolyMesh::quad_count() const {
  return std::size_t(std::count_if(faces.begin(), faces.end(), [](const auto& f) { return f[3] >= 0; }));
}

void PolyMesh::validate(const std::string& what) const {
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const int n = faces[f][3] >= 0 ? 4 : 3;
    for (int k = 0; k < n; ++k) {
      const int v = faces[f][std::size_t(k)];
      if (v < 0 || std::size_t(v) >= vertices.size())
        throw InputError(what + ": face " + std::to_string(f) + " has vertex index " + std::to_string(v) +
                         "; expected an index in [0, " + std::to_string(vertices.size()) + ")");
      for (int l = 0; l < k; ++l)
        if (faces[f][std::size_t(l)] == v)
          throw InputError(what + ": face " + std::to_string(f) + " repeats vertex " + std::to_string(v) +
                           "; expected distinct corners");
    }
  }
}

}  // namespace pm
