// Crinkle-clipped pictures of labelled tetrahedral meshes (see pm/render/tet_render.h).
#include "pm/render/tet_render.h"

#include <algorithm>
#include <cstdint>
#include <unordered_map>

#include "pm/base/error.h"

namespace pm {

Mesh tet_render_mesh(const LabelledTets& t, const RenderParams& p) {
  t.validate("render");
  std::vector<char> kept(t.tets.size(), 1);
  if (!p.clip.empty()) {
    const ClipPlane cp = clip_plane(t.vertices, p, fit_camera(t.vertices, p));
    for (std::size_t i = 0; i < t.tets.size(); ++i) {
      double c = 0;
      for (int v : t.tets[i]) c += t.vertices[std::size_t(v)][cp.axis];
      if ((c / 4 - cp.position) * cp.removed_side > 0) kept[i] = 0;
    }
  }
  // Faces of the kept tetrahedra; those used once bound the kept set.
  struct Use {
    int count = 0;
    std::size_t tet = 0;
    int face = 0;
  };
  std::unordered_map<std::uint64_t, Use> faces;
  faces.reserve(t.tets.size() * 2);
  // Corners of the face opposite each corner, ordered to face away from it
  // for a positively oriented tetrahedron.
  static const int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  auto key = [](int a, int b, int c) {
    int v[3] = {a, b, c};
    std::sort(v, v + 3);
    return (std::uint64_t(v[0]) << 42) ^ (std::uint64_t(v[1]) << 21) ^ std::uint64_t(v[2]);
  };
  for (std::size_t i = 0; i < t.tets.size(); ++i) {
    if (!kept[i]) continue;
    const auto& c = t.tets[i];
    for (int f = 0; f < 4; ++f) {
      Use& u = faces[key(c[std::size_t(kFace[f][0])], c[std::size_t(kFace[f][1])], c[std::size_t(kFace[f][2])])];
      if (u.count++ == 0) {
        u.tet = i;
        u.face = f;
      }
    }
  }
  Mesh m;
  m.vertices = t.vertices;
  auto& material = m.face_ints["material"];
  // In tetrahedron order, so the picture does not depend on the hash map's order.
  std::vector<std::pair<std::size_t, int>> boundary;
  for (const auto& [k, u] : faces)
    if (u.count == 1) boundary.emplace_back(u.tet, u.face);
  std::sort(boundary.begin(), boundary.end());
  for (const auto& [i, f] : boundary) {
    const auto& c = t.tets[i];
    std::array<int, 3> tri{c[std::size_t(kFace[f][0])], c[std::size_t(kFace[f][1])], c[std::size_t(kFace[f][2])]};
    const Vec3 &a = t.vertices[std::size_t(c[0])], &b = t.vertices[std::size_t(c[1])],
               &d = t.vertices[std::size_t(c[2])], &e = t.vertices[std::size_t(c[3])];
    if (dot(b - a, cross(d - a, e - a)) < 0) std::swap(tri[1], tri[2]);  // negatively oriented tetrahedron
    m.faces.push_back(tri);
    material.push_back(t.materials[i]);
  }
  return m;
}

Image render_tets(const LabelledTets& t, const RenderParams& params) {
  if (params.mode != "auto" && params.mode != "mesh")
    throw UsageError("render: mode " + quote(params.mode) + " for a tetrahedral mesh; expected auto or mesh");
  if (!params.color_by.empty() && params.color_by != "material")
    throw UsageError("render: --color-by " + quote(params.color_by) +
                     " for a tetrahedral mesh; expected material (the only property drawn)");
  const Mesh m = tet_render_mesh(t, params);
  if (m.faces.empty())
    throw InputError("render: the clip " + quote(params.clip) +
                     " removes every tetrahedron; expected a plane through the mesh (e.g. x:0.5)");
  RenderParams p = params;
  p.mode = "mesh";
  p.color_by = "material";
  p.clip.clear();  // done above, on whole tetrahedra
  return render(m, p);
}

}  // namespace pm
