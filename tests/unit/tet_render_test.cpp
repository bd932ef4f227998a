// Pictures of tetrahedral meshes (pm/render/tet_render.h): the crinkle clip
// keeps whole tetrahedra on the far side of the plane, the cut shows every
// material there in its own colour and nothing of the removed side.
#include <gtest/gtest.h>

#include "pm/base/error.h"
#include "pm/render/tet_render.h"
#include "tet_fixtures.h"
#include "test_images.h"

namespace pm {
namespace {

// [0, 2] x [0, 1] x [0, 1] in cubes of 0.25: material 3 beyond x = 1.5, else
// 1 below y = 0.5 and 2 above.
LabelledTets three_materials() {
  return test::tet_box(8, 4, 4, 0.25, [](const Vec3& c) { return c.x > 1.5 ? 3 : c.y < 0.5 ? 1 : 2; });
}

using testing::pixels_of_shade;

TEST(TetRender, WithoutClipTheBoundaryIsDrawn) {
  const LabelledTets t = three_materials();
  const Mesh m = tet_render_mesh(t, {});
  // The box's surface: 2 * (8*4 + 8*4 + 4*4) squares of 2 triangles.
  EXPECT_EQ(m.faces.size(), 2u * 2 * (32 + 32 + 16));
  ASSERT_EQ(m.face_ints.at("material").size(), m.faces.size());
  RenderParams p;
  p.width = p.height = 300;
  const Image img = render_tets(t, p);
  for (int mat : {1, 2, 3}) EXPECT_GT(pixels_of_shade(img, category_color(mat)), 500u) << mat;
}

TEST(TetRender, CrinkleClipKeepsWholeTetrahedraOnTheFarSide) {
  const LabelledTets t = three_materials();
  RenderParams p;  // azimuth 30, elevation 20: the camera looks from +x, +y, +z
  p.clip = "x:0.5";  // x = 1
  const Mesh m = tet_render_mesh(t, p);
  // Whole cubes lie on either side of x = 1: the kept half's surface, with the flat cut.
  EXPECT_EQ(m.faces.size(), 2u * 2 * (16 + 16 + 16));
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    for (int v : m.faces[f]) EXPECT_LE(m.vertices[std::size_t(v)].x, 1.0 + 1e-12);
    EXPECT_NE(m.face_ints.at("material")[f], 3);  // all of material 3 is on the removed side
  }
  // An oblique plane cuts through cubes: tetrahedra whole, by centroid.
  p.clip = "x:0.41";
  const Mesh jagged = tet_render_mesh(t, p);
  double xmax = 0;
  for (const auto& f : jagged.faces)
    for (int v : f) xmax = std::max(xmax, jagged.vertices[std::size_t(v)].x);
  EXPECT_GT(xmax, 0.82);  // some kept tetrahedra reach over the plane ...
  EXPECT_LE(xmax, 1.0);   // ... by less than a cube

  p.clip = "x:0.5";
  p.width = p.height = 300;
  p.legend = true;
  p.edges = true;
  const Image img = render_tets(t, p);
  EXPECT_GT(pixels_of_shade(img, category_color(1)), 500u);  // both materials on the cut
  EXPECT_GT(pixels_of_shade(img, category_color(2)), 500u);
  EXPECT_EQ(pixels_of_shade(img, category_color(3)), 0u);  // nothing of the removed side, legend included
  // The legend names the two materials shown: swatches at (4, 4) and (4, 14).
  auto is = [&](int x, int y, const Vec3& c) {
    const std::uint8_t* q = img.at(x, y);
    for (int k = 0; k < 3; ++k)
      if (q[k] != std::lround(255 * c[k])) return false;
    return true;
  };
  EXPECT_TRUE(is(6, 6, category_color(1)));
  EXPECT_TRUE(is(6, 16, category_color(2)));

  // Seen from -x, the same plane removes the other side.
  p.azimuth_deg = 210;
  p.clip = "x:0.5";
  const Mesh other = tet_render_mesh(t, p);
  for (const auto& f : other.faces)
    for (int v : f) EXPECT_GE(other.vertices[std::size_t(v)].x, 1.0 - 1e-12);
}

TEST(TetRender, BadInput) {
  const LabelledTets t = three_materials();
  RenderParams p;
  p.mode = "splats";
  EXPECT_THROW(render_tets(t, p), UsageError);
  p = {};
  p.color_by = "height";
  EXPECT_THROW(render_tets(t, p), UsageError);
  p = {};
  p.clip = "q";
  EXPECT_THROW(render_tets(t, p), UsageError);
  p.clip = "x:0";  // the plane at the low end of x, the camera on +x: every tetrahedron is removed
  EXPECT_THROW(render_tets(t, p), InputError);
  LabelledTets bad = t;
  bad.tets[0][0] = 100000;
  EXPECT_THROW(render_tets(bad, {}), InputError);
}

}  // namespace
}  // namespace pm
