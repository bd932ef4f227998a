#include "pm/cli/field_options.h"

#include <sstream>

#include "pm/base/error.h"
#include "pm/field/implicits.h"
#include "pm/field/volume_field.h"
#include "pm/io/volume_io.h"

namespace pm {

void add_field_options(CLI::App& app, FieldOptions& o) {
  app.add_option("-i,--input", o.input, "Volume holding the field F (NRRD, VDB, MHA, NIfTI, INR); world units from its header");
  app.add_option("--implicit", o.implicit, "Analytic implicit instead of a volume: " + implicit_help());
  app.add_option("--iso", o.iso, "Isovalue c: the surface is F = c, with F < c inside")->capture_default_str();
  app.add_option("--kernel", o.kernel,
                 "Reconstruction of volumes: bspline (approximating, C2), catmull-rom (interpolating, C1), "
                 "mix (Catmull-Rom value, B-spline derivatives)")
      ->capture_default_str();
}

LoadedField load_field(const FieldOptions& o) {
  if (o.input.empty() == o.implicit.empty())
    throw UsageError("give exactly one of --input FILE and --implicit SPEC");
  LoadedField lf;
  lf.iso = o.iso;
  if (!o.implicit.empty()) {
    lf.field = make_implicit(o.implicit);
    return lf;
  }
  VolumeFieldParams vp;
  if (o.kernel == "bspline") vp = {KernelType::bspline, KernelType::bspline};
  else if (o.kernel == "catmull-rom") vp = {KernelType::catmull_rom, KernelType::catmull_rom};
  else if (o.kernel == "mix") vp = VolumeFieldParams::chapter5_mix();
  else throw UsageError("--kernel \"" + o.kernel + "\" is unknown; expected bspline, catmull-rom or mix");
  const Volume v = read_volume(o.input);
  require_finite(v, quote(o.input));
  lf.range = value_range(v);
  lf.from_volume = true;
  if (!(o.iso > lf.range.lo && o.iso < lf.range.hi)) {
    std::ostringstream m;
    m << quote(o.input) << ": no surface: the isovalue " << o.iso << " is outside the value range [" << lf.range.lo
      << ", " << lf.range.hi << "]; expected lo < iso < hi";
    throw InputError(m.str());
  }
  lf.field = std::make_unique<VolumeField>(v, vp, o.input);
  return lf;
}

}  // namespace pm
