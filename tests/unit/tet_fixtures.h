#pragma once
// Labelled tetrahedral meshes generated for the tests: a box of nx × ny × nz
// cubes of side h, each cut into 6 positively oriented tetrahedra around its
// diagonal (Kuhn), with the material of each tetrahedron chosen by a function
// of its centroid and the boundary and interface triangles listed.
#include <algorithm>
#include <array>
#include <functional>
#include <map>

#include "pm/io/tet_mesh.h"

namespace pm::test {

inline LabelledTets tet_box(int nx, int ny, int nz, double h, const std::function<int(const Vec3&)>& material,
                            const Vec3& origin = {0, 0, 0}) {
  LabelledTets t;
  auto id = [&](int i, int j, int k) { return (k * (ny + 1) + j) * (nx + 1) + i; };
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i) t.vertices.push_back(origin + Vec3(i * h, j * h, k * h));
  static const int kKuhn[6][4] = {{0, 1, 3, 7}, {0, 1, 7, 5}, {0, 2, 7, 3}, {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 7, 6}};
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (const auto& q : kKuhn) {
          std::array<int, 4> c{};
          for (int v = 0; v < 4; ++v) c[std::size_t(v)] = id(i + (q[v] & 1), j + ((q[v] >> 1) & 1), k + (q[v] >> 2));
          const Vec3 &a = t.vertices[std::size_t(c[0])], &b = t.vertices[std::size_t(c[1])],
                     &d = t.vertices[std::size_t(c[2])], &e = t.vertices[std::size_t(c[3])];
          if (dot(b - a, cross(d - a, e - a)) < 0) std::swap(c[2], c[3]);
          t.tets.push_back(c);
          t.materials.push_back(material((a + b + d + e) / 4.0));
        }
  // Boundary faces (one tetrahedron) and interfaces (two of different materials).
  struct Use {
    int n = 0;
    std::array<int, 3> v{};
    int m0 = 0, m1 = 0;
  };
  std::map<std::array<int, 3>, Use> faces;
  static const int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (std::size_t i = 0; i < t.tets.size(); ++i)
    for (const auto& f : kFace) {
      std::array<int, 3> v{t.tets[i][std::size_t(f[0])], t.tets[i][std::size_t(f[1])], t.tets[i][std::size_t(f[2])]};
      std::array<int, 3> key = v;
      std::sort(key.begin(), key.end());
      Use& u = faces[key];
      (u.n == 0 ? u.m0 : u.m1) = t.materials[i];
      if (u.n++ == 0) u.v = v;
    }
  for (const auto& [key, u] : faces)
    if (u.n == 1 || u.m0 != u.m1) {
      t.triangles.push_back(u.v);
      t.triangle_labels.push_back(u.n == 1 ? std::array<int, 2>{0, u.m0}
                                           : std::array<int, 2>{std::min(u.m0, u.m1), std::max(u.m0, u.m1)});
    }
  return t;
}

}  // namespace pm::test
