// Nektar++ field reader (pm::read_nektar_field), then HpField on two fixed
// meshes (two tetrahedra, two hexahedra; element ids 0 and 1), evaluation and
// the lattice isosurface baseline on whatever field was accepted.
#include "../unit/nektar_fixtures.h"
#include "fuzz_util.h"
#include "pm/baseline/lattice_iso.h"
#include "pm/field/hp_field.h"
#include "pm/io/nektar.h"

namespace {
const pm::NektarMesh& mesh(bool hex) {
  static const pm::NektarMesh tets = [] {
    pm::test::GenMesh t;
    int v[5];
    const pm::Vec3 p[5] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
    for (int k = 0; k < 5; ++k) v[k] = t.vertex(p[k]);
    t.add_tet({v[0], v[1], v[2], v[3]});
    t.add_tet({v[1], v[2], v[3], v[4]});
    const std::string path = pm::fuzz::work_dir() + "/tets.xml";
    pm::test::write_text(path, pm::test::mesh_xml(t, false));
    return pm::read_nektar_mesh(path);
  }();
  static const pm::NektarMesh hexes = [] {
    pm::test::GenMesh h;
    int w[3][2][2];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 2; ++j)
        for (int k = 0; k < 2; ++k) w[i][j][k] = h.vertex({double(i), double(j), double(k)});
    h.add_hex({w[0][0][0], w[1][0][0], w[1][1][0], w[0][1][0], w[0][0][1], w[1][0][1], w[1][1][1], w[0][1][1]});
    h.add_hex({w[1][0][0], w[2][0][0], w[2][1][0], w[1][1][0], w[1][0][1], w[2][0][1], w[2][1][1], w[1][1][1]});
    const std::string path = pm::fuzz::work_dir() + "/hexes.xml";
    pm::test::write_text(path, pm::test::mesh_xml(h, true));
    return pm::read_nektar_mesh(path);
  }();
  return hex ? hexes : tets;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = pm::fuzz::put_file("fuzz.fld", data, size);
  pm::fuzz::expect_pm_errors_only([&] {
    const pm::NektarField f = pm::read_nektar_field(path);
    if (f.elements.empty()) return;
    const pm::HpField h(mesh(f.elements[0].shape == pm::NektarShape::Hexahedron), f, f.names[0]);
    for (int e = 0; e < h.num_elements(); ++e) {
      pm::Vec3 g;
      pm::Mat3 H;
      (void)h.ref_evaluate(e, {-0.5, -0.5, -0.5}, g, H);
    }
    pm::LatticeIsoParams p;
    p.points = 3;
    (void)pm::lattice_isosurface(h, 0.1, p);
  });
  return 0;
}
