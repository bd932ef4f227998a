// The Chapter 4 baseline (pm/baseline/lattice_iso.h): equispaced lattice per
// element + linear marching tetrahedra, as FieldConvert's isocontour.
#include "pm/baseline/lattice_iso.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "nektar_fixtures.h"
#include "pm/base/error.h"
#include "test_util.h"

namespace pm {
namespace {

using test::GenBlock;
using test::GenMesh;

std::string write(const std::string& name, const std::string& text) {
  const std::string p = test::temp_dir() + "/" + name;
  test::write_text(p, text);
  return p;
}

TEST(LatticeIso, LinearInterpolationOnTheLatticeIsWhatItReturns) {
  // u = z^2 (a cubic in 4 modes) on the two hexahedra; u = 0.25 is z = 0.5.
  // With 4 lattice points per edge (z = 0, 1/3, 2/3, 1) marching tetrahedra
  // put every vertex at z = 1/3 + (0.25 - 1/9) / (4/9 - 1/9) / 3 = 0.47222...
  GenMesh m;
  int v[3][2][2];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 2; ++j)
      for (int k = 0; k < 2; ++k) v[i][j][k] = m.vertex({double(i), double(j), double(k)});
  m.add_hex({v[0][0][0], v[1][0][0], v[1][1][0], v[0][1][0], v[0][0][1], v[1][0][1], v[1][1][1], v[0][1][1]});
  m.add_hex({v[2][1][0], v[1][1][0], v[1][0][0], v[2][0][0], v[2][1][1], v[1][1][1], v[1][0][1], v[2][0][1]});
  const NektarMesh mesh = read_nektar_mesh(write("z2.xml", test::mesh_xml(m, true)));
  GenBlock blk;
  blk.ids = "0-1";
  const std::array<std::array<double, 4>, 3> g = {{{1, 0, 0, 0}, {1, 0, 0, 0}, {0, 0, 1, 0}}};
  for (const auto& lohi : {std::make_pair(Vec3{0, 0, 0}, Vec3{1, 1, 1}), std::make_pair(Vec3{2, 1, 0}, Vec3{1, 0, 1})}) {
    const auto c = test::hex_product_coeffs(g, lohi.first, lohi.second);
    blk.coeffs.insert(blk.coeffs.end(), c.begin(), c.end());
  }
  const HpField f(mesh, read_nektar_field(write("z2.fld", test::field_xml({blk}))), "u");
  LatticeIsoParams p;
  p.points = 4;
  const LatticeIsoResult r = lattice_isosurface(f, 0.25, p);
  EXPECT_EQ(r.field_evaluations, 2u * 64);
  EXPECT_EQ(r.lattice_tets, 2u * 27 * 6);
  ASSERT_FALSE(r.mesh.faces.empty());
  const double want = 1.0 / 3 + (0.25 - 1.0 / 9) / (3.0 / 9) / 3;
  for (const Vec3& v : r.mesh.vertices) EXPECT_NEAR(v.z, want, 1e-14);
  // Welded, also across the shared face x = 1.
  for (std::size_t a = 0; a < r.mesh.vertices.size(); ++a)
    for (std::size_t b = a + 1; b < r.mesh.vertices.size(); ++b)
      EXPECT_GT(norm(r.mesh.vertices[a] - r.mesh.vertices[b]), 1e-9);
  // Oriented towards increasing u (+z).
  for (const auto& tri : r.mesh.faces) {
    const Vec3 n = cross(r.mesh.vertices[tri[1]] - r.mesh.vertices[tri[0]], r.mesh.vertices[tri[2]] - r.mesh.vertices[tri[0]]);
    EXPECT_GT(n.z, 0);
  }
  EXPECT_THROW(lattice_isosurface(f, 0.25, LatticeIsoParams{1, true}), UsageError);
}

TEST(LatticeIsoShared, Chan3DErrorAtFieldConvertDefaultAndBeyond) {
  // Issue #18: at FieldConvert's default lattice (modes + 1 = 5 points per
  // edge) the u = 0.5 surface of u = 1 - z^2 lands at |z| = 2/3 instead of
  // 1/sqrt(2), an error of 5.7%. Prints the table of docs/CHAPTER4.md.
  PM_REQUIRE_SHARED(dir, "nektar-highorder");
  const HpField f(read_nektar_mesh(dir + "/chan3D.xml"), read_nektar_field(dir + "/chan3D.fld"), "u");
  const double zs = std::sqrt(0.5);
  std::printf("lattice points/edge  evaluations  triangles  max rel. error of |z|\n");
  double err5 = 0;
  for (int n : {0, 3, 4, 6, 8, 12, 16, 24, 32, 48}) {
    LatticeIsoParams p;
    p.points = n;
    const LatticeIsoResult r = lattice_isosurface(f, 0.5, p);
    double err = 0;
    for (const Vec3& v : r.mesh.vertices) err = std::max(err, std::fabs(std::fabs(v.z) - zs) / zs);
    std::printf("%19d  %11llu  %9zu  %.3e\n", n ? n : 5, static_cast<unsigned long long>(r.field_evaluations),
                r.mesh.faces.size(), err);
    if (n == 0) {
      err5 = err;
      EXPECT_EQ(r.field_evaluations, 6u * 35);  // 6 tetrahedra x 35 lattice points
      for (const Vec3& v : r.mesh.vertices) EXPECT_NEAR(std::fabs(v.z), 2.0 / 3, 1e-12);
    }
  }
  EXPECT_NEAR(err5, (zs - 2.0 / 3) / zs, 1e-12);
}

}  // namespace
}  // namespace pm
