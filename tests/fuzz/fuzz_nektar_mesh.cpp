// Nektar++ mesh reader (pm::read_nektar_mesh), then an HpField of a linear
// field on whatever mesh it accepted (element set-up, adjacency, location).
#include "fuzz_util.h"
#include "pm/field/hp_field.h"
#include "pm/io/nektar.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = pm::fuzz::put_file("fuzz.xml", data, size);
  pm::fuzz::expect_pm_errors_only([&] {
    const pm::NektarMesh m = pm::read_nektar_mesh(path);
    if (m.elements.size() > 10000) return;
    pm::NektarField f;
    f.path = "fuzz.fld";
    f.names = {"u"};
    for (const auto& e : m.elements) {
      pm::NektarFieldElement fe;
      fe.id = e.id;
      fe.shape = e.shape;
      fe.modes = {2, 2, 2};
      fe.ncoeffs = pm::nektar_num_coeffs(e.shape, fe.modes);
      fe.coeffs.assign(fe.ncoeffs, 1.0);
      f.element_index[fe.id] = static_cast<int>(f.elements.size());
      f.elements.push_back(fe);
    }
    const pm::HpField h(m, f, "u");
    const pm::Box b = h.domain();
    for (int k = 0; k < 4; ++k) {
      const double t = (k + 0.5) / 4;
      (void)h.value(b.lo + t * (b.hi - b.lo));
    }
  });
  return 0;
}
