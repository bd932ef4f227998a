#pragma once
// Small exact meshes shared by the unit tests.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "pm/base/mesh.h"

namespace pm {
namespace testing {

/// Icosahedron subdivided `levels` times, projected onto the sphere of
/// radius r about `centre`; faces wound outward. 20·4^levels faces.
inline Mesh icosphere(int levels, double r = 1, Vec3 centre = {}) {
  const double t = (1 + std::sqrt(5.0)) / 2;
  Mesh m;
  m.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  m.faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      m.vertices.push_back((m.vertices[std::size_t(a)] + m.vertices[std::size_t(b)]) * 0.5);
      return mid[key] = int(m.vertices.size()) - 1;
    };
    std::vector<std::array<int, 3>> faces;
    for (const auto& f : m.faces) {
      const int ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]), ca = midpoint(f[2], f[0]);
      faces.push_back({f[0], ab, ca});
      faces.push_back({f[1], bc, ab});
      faces.push_back({f[2], ca, bc});
      faces.push_back({ab, bc, ca});
    }
    m.faces = std::move(faces);
  }
  for (Vec3& v : m.vertices) v = normalized(v) * r + centre;
  return m;
}

}  // namespace testing
}  // namespace pm
