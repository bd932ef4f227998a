#include "pm/field/field.h"

namespace pm {

bool material_below_iso(const ScalarField& f, double iso) {
  const Box d = f.domain();
  int above = 0;
  for (int c = 0; c < 8; ++c) {
    const Vec3 x((c & 1) ? d.hi.x : d.lo.x, (c & 2) ? d.hi.y : d.lo.y, (c & 4) ? d.hi.z : d.lo.z);
    above += f.value(x) > iso;
  }
  return above >= 4;
}

}  // namespace pm
