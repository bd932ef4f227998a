#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>

#include "pm/base/error.h"
#include "pm/render/render.h"
#include "test_images.h"

namespace pm {
namespace {

constexpr double kPi = 3.14159265358979323846;

// n points on the unit sphere (Fibonacci spiral) with outward normals.
Mesh fibonacci_sphere(int n) {
  Mesh m;
  const double golden = kPi * (3 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1 - 2 * (i + 0.5) / n, r = std::sqrt(1 - z * z), a = golden * i;
    m.vertices.push_back({r * std::cos(a), r * std::sin(a), z});
  }
  m.normals = m.vertices;
  return m;
}

bool is_background(const Image& img, int x, int y) {
  const std::uint8_t* p = img.at(x, y);
  return p[0] == 255 && p[1] == 255 && p[2] == 255;
}

std::size_t covered(const Image& img) {
  std::size_t n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) n += !is_background(img, x, y);
  return n;
}

class SphereCoverage : public ::testing::TestWithParam<std::string> {};

TEST_P(SphereCoverage, DiskOfExpectedRadiusWithoutHoles) {
  const Mesh m = fibonacci_sphere(20000);
  RenderParams p;
  p.width = p.height = 400;
  p.mode = GetParam();
  const Image img = render(m, p);
  ASSERT_EQ(img.width, 400);
  ASSERT_EQ(img.height, 400);
  const Camera cam = render_camera(m, p);
  const Vec3 c = cam.project({0, 0, 0});
  const double r_px = cam.scale;  // unit sphere
  ASSERT_GT(r_px, 100);
  const double expected = kPi * r_px * r_px;
  EXPECT_NEAR(double(covered(img)), expected, 0.05 * expected);
  std::size_t holes = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      if (std::hypot(x + 0.5 - c.x, y + 0.5 - c.y) < 0.9 * r_px) holes += is_background(img, x, y);
  EXPECT_EQ(holes, 0u);
}

INSTANTIATE_TEST_SUITE_P(Modes, SphereCoverage, ::testing::Values("splats", "disks"));

TEST(Render, SplatsAreSmoothlyShaded) {
  // Neighbouring pixels inside the sphere differ little: normals are blended.
  const Mesh m = fibonacci_sphere(20000);
  RenderParams p;
  p.width = p.height = 300;
  const Image img = render(m, p);  // auto = splats for a point set
  const Camera cam = render_camera(m, p);
  const Vec3 c = cam.project({0, 0, 0});
  int worst = 0;
  for (int y = 1; y < img.height; ++y)
    for (int x = 1; x < img.width; ++x) {
      if (std::hypot(x + 0.5 - c.x, y + 0.5 - c.y) > 0.8 * cam.scale) continue;
      worst = std::max({worst, std::abs(img.at(x, y)[1] - img.at(x - 1, y)[1]),
                        std::abs(img.at(x, y)[1] - img.at(x, y - 1)[1])});
    }
  EXPECT_LE(worst, 6);
}

TEST(Render, SingleTriangleCoversItsArea) {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0.2, 0}, {0.3, 1, 0.5}};
  m.faces = {{0, 1, 2}};
  RenderParams p;
  p.width = 500;
  p.height = 400;
  const Image img = render(m, p);
  const Camera cam = fit_camera(m.vertices, p);
  const Vec3 a = cam.project(m.vertices[0]), b = cam.project(m.vertices[1]), c = cam.project(m.vertices[2]);
  const double area = 0.5 * std::fabs((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x));
  const double perimeter = std::hypot(b.x - a.x, b.y - a.y) + std::hypot(c.x - b.x, c.y - b.y) +
                           std::hypot(a.x - c.x, a.y - c.y);
  ASSERT_GT(area, 5000);
  EXPECT_NEAR(double(covered(img)), area, 0.5 * perimeter);
  // The projected centroid is covered, a point well outside is not.
  EXPECT_FALSE(is_background(img, int((a.x + b.x + c.x) / 3), int((a.y + b.y + c.y) / 3)));
  EXPECT_TRUE(is_background(img, 2, 2));
}

TEST(Render, CameraFollowsAzimuthElevationAndUpAxis) {
  const std::vector<Vec3> box = {{-1, -1, -1}, {1, 1, 1}};
  RenderParams p;
  p.azimuth_deg = 0;
  p.elevation_deg = 0;
  Camera cam = fit_camera(box, p);  // up z, looking from +x
  EXPECT_LT(cam.project({0, 0, 1}).y, 400);   // +z is up on screen
  EXPECT_GT(cam.project({0, 1, 0}).x, 400);   // +y is to the right
  EXPECT_LT(cam.project({1, 0, 0}).z, cam.project({-1, 0, 0}).z);  // +x is nearer
  p.azimuth_deg = 90;
  cam = fit_camera(box, p);
  EXPECT_LT(cam.project({0, 1, 0}).z, cam.project({0, -1, 0}).z);  // now +y is nearer
  p.up = "y";
  p.azimuth_deg = 0;
  p.elevation_deg = 90;
  cam = fit_camera(box, p);
  EXPECT_LT(cam.project({0, 1, 0}).z, cam.project({0, -1, 0}).z);  // looking down -y
  EXPECT_NEAR(cam.scale, 800 / (2 * 1.05 * std::sqrt(3.0)), 1e-9);
}

TEST(Render, ColorByPicksDistinctColours) {
  // Two triangles side by side with face labels 0 and 1, and a vertex scalar.
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {3, 0, 0}, {2, 1, 0}};
  m.faces = {{0, 1, 2}, {3, 4, 5}};
  m.face_ints["label_a"] = {0, 1};
  m.vertex_scalars["s"] = {0, 0, 0, 1, 1, 1};
  RenderParams p;
  p.width = p.height = 200;
  p.elevation_deg = 90;  // look down z
  const Camera cam = fit_camera(m.vertices, p);
  auto colour_at = [&](const Image& img, const Vec3& w) {
    const Vec3 s = cam.project(w);
    const std::uint8_t* px = img.at(int(s.x), int(s.y));
    return std::make_tuple(px[0], px[1], px[2]);
  };
  const Vec3 left{0.3, 0.3, 0}, right{2.3, 0.3, 0};
  std::set<std::tuple<int, int, int>> seen;
  const Image plain = render(m, p);
  EXPECT_EQ(colour_at(plain, left), colour_at(plain, right));
  seen.insert(colour_at(plain, left));
  for (const char* prop : {"label_a", "s"}) {
    p.color_by = prop;
    const Image img = render(m, p);
    EXPECT_NE(colour_at(img, left), colour_at(img, right)) << prop;
    seen.insert(colour_at(img, left));
    seen.insert(colour_at(img, right));
  }
  EXPECT_EQ(seen.size(), 5u);  // plain, two labels, two scalar ends: all different

  p.color_by = "nope";
  try {
    render(m, p);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("\"nope\""), std::string::npos) << msg;
    EXPECT_NE(msg.find("s (vertex), label_a (face)"), std::string::npos) << msg;
  }
  p.color_by = "label_a";
  p.mode = "splats";
  EXPECT_THROW(render(m, p), InputError);  // face labels cannot colour points
}

TEST(Render, EdgesDarkenTriangleBorders) {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  RenderParams p;
  p.width = p.height = 200;
  p.elevation_deg = 90;
  const Image plain = render(m, p);
  p.edges = true;
  const Image lined = render(m, p);
  std::size_t d = 0;  // pixels made clearly darker
  for (std::size_t i = 0; i < plain.rgb.size(); i += 3) d += lined.rgb[i + 1] + 40 < plain.rgb[i + 1];
  const Camera cam = fit_camera(m.vertices, p);
  // The square's four sides plus its diagonal, about a pixel wide.
  const double length_px = (4 + std::sqrt(2.0)) * cam.scale;
  EXPECT_GT(double(d), 0.5 * length_px);
  EXPECT_LT(double(d), 2.5 * length_px);
}

TEST(Render, DeterministicAndMeanSpacingIsRight) {
  const Mesh m = fibonacci_sphere(3000);
  RenderParams p;
  p.width = p.height = 120;
  EXPECT_EQ(render(m, p).rgb, render(m, p).rgb);

  std::vector<Vec3> grid;
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 20; ++j) grid.push_back({0.1 * i, 0.1 * j, 0.0});
  EXPECT_NEAR(mean_nearest_neighbor_distance(grid), 0.1, 1e-9);
  // Interior grid point 5 * 20 + 5: four neighbours at 0.1, then four at 0.1 * sqrt(2).
  const std::vector<double> d4 = nearest_neighbor_distances(grid, 4), d5 = nearest_neighbor_distances(grid, 5);
  EXPECT_NEAR(d4[105], 0.1, 1e-9);
  EXPECT_NEAR(d5[105], 0.1 * std::sqrt(2.0), 1e-9);
  EXPECT_NEAR(d5[0], 0.2, 1e-9);  // corner: 0.1, 0.1, 0.1414, 0.2, 0.2
  std::vector<Vec3> cube;  // volume-filling: the grid has to grow
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j)
      for (int k = 0; k < 12; ++k) cube.push_back({0.5 * i, 0.5 * j, 0.5 * k});
  EXPECT_NEAR(mean_nearest_neighbor_distance(cube), 0.5, 1e-9);
  EXPECT_EQ(mean_nearest_neighbor_distance({{1, 2, 3}}), 0.0);
}

// Interface mesh of two nested axis-aligned cubes (half sides 2 and 1), outward
// winding: the outer one separates 0|1 (pair 0), the inner one 1|2 (pair 1).
Mesh nested_cubes() {
  Mesh m;
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (int c = 0; c < 2; ++c) {
    const double h = c == 0 ? 2 : 1;
    const int off = int(m.vertices.size());
    for (int k = 0; k < 8; ++k) m.vertices.push_back({k & 1 ? h : -h, k & 2 ? h : -h, k & 4 ? h : -h});
    for (const auto& q : quads) {
      m.faces.push_back({off + q[0], off + q[1], off + q[2]});
      m.faces.push_back({off + q[0], off + q[2], off + q[3]});
      for (int t = 0; t < 2; ++t) {
        m.face_ints["label_a"].push_back(c);
        m.face_ints["label_b"].push_back(c + 1);
        m.face_ints["pair"].push_back(c);
      }
    }
  }
  return m;
}

using testing::pixels_of_shade;

TEST(Render, LegendNamesEachPairAndClipShowsTheInside) {
  const Mesh m = nested_cubes();
  RenderParams p;
  p.width = p.height = 400;
  p.color_by = "pair";
  const Vec3 outer = category_color(0), inner = category_color(1);
  const Image plain = render(m, p);
  EXPECT_GT(pixels_of_shade(plain, outer), 1000u);
  EXPECT_EQ(pixels_of_shade(plain, inner), 0u);  // the inner cube is hidden

  p.legend = true;
  const Image key = render(m, p);
  // Swatches at (4, 4) and (4, 14), 8x7 pixels, in the flat pair colours; text "0-1" then "1-2"
  // to their right: the top row of the glyph '0' is set in columns 1-3 (pixel x 16).
  auto is = [&](int x, int y, const Vec3& c) {
    const std::uint8_t* q = key.at(x, y);
    for (int k = 0; k < 3; ++k)
      if (q[k] != std::lround(255 * c[k])) return false;
    return true;
  };
  EXPECT_TRUE(is(6, 6, outer));
  EXPECT_TRUE(is(6, 16, inner));
  EXPECT_FALSE(is_background(key, 16, 4));
  EXPECT_TRUE(is_background(key, 15, 4));
  EXPECT_FALSE(is_background(key, 17, 14));  // '1' of "1-2": 0x04, column 2 (x 17)

  p.legend = false;
  p.clip = "x";
  const Image cut = render(m, p);
  EXPECT_GT(pixels_of_shade(cut, inner), 500u);  // the inner cube shows through the cut
  EXPECT_GT(pixels_of_shade(cut, outer), 500u);
  p.clip = "x:1";  // the plane at the box's far end on the camera's side: nothing cut
  EXPECT_EQ(pixels_of_shade(render(m, p), inner), 0u);
  p.clip = "w";
  EXPECT_THROW(render(m, p), UsageError);
  p.clip = "x:2";
  EXPECT_THROW(render(m, p), UsageError);
}

// A label map with dozens of tissues (the frog has 83 interfaces): the key lists
// every value in columns, and the colours beyond the 12 fixed ones stay apart.
TEST(Render, LegendInColumnsWithDistinctColours) {
  constexpr int kValues = 60;
  for (int a = 0; a < kValues; ++a)
    for (int b = a + 1; b < kValues; ++b) {
      const Vec3 ca = category_color(a), cb = category_color(b);
      const double d = std::max({std::fabs(ca[0] - cb[0]), std::fabs(ca[1] - cb[1]), std::fabs(ca[2] - cb[2])});
      EXPECT_GT(d, 0.02) << a << " " << b;
    }
  Mesh m;
  for (int v = 0; v < kValues; ++v) {
    const double x = double(v);
    m.vertices.push_back({x, 0, 0});
    m.vertices.push_back({x + 1, 0, 0});
    m.vertices.push_back({x, 1, 0});
    m.faces.push_back({3 * v, 3 * v + 1, 3 * v + 2});
    m.face_ints["tissue"].push_back(v);
  }
  RenderParams p;
  p.width = p.height = 400;
  p.color_by = "tissue";
  p.legend = true;
  const Image key = render(m, p);
  // 39 entries per column ((400 - 8) / 10), columns 8 + 3 + 4 * 6 + 4 = 39 pixels wide.
  for (int v = 0; v < kValues; ++v) {
    const int x = 4 + (v / 39) * 39 + 2, y = 4 + (v % 39) * 10 + 2;
    const std::uint8_t* q = key.at(x, y);
    const Vec3 c = category_color(v);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(q[k], std::lround(255 * c[k])) << "value " << v;
  }
}

TEST(Render, BadInput) {
  Mesh empty;
  EXPECT_THROW(render(empty, {}), InputError);
  Mesh pts = fibonacci_sphere(10);
  RenderParams p;
  p.width = 0;
  EXPECT_THROW(render(pts, p), UsageError);
  p = {};
  p.height = 9000;
  EXPECT_THROW(render(pts, p), UsageError);
  p = {};
  p.mode = "voxels";
  EXPECT_THROW(render(pts, p), UsageError);
  p = {};
  p.mode = "mesh";
  EXPECT_THROW(render(pts, p), InputError);  // no faces
}

}  // namespace
}  // namespace pm
