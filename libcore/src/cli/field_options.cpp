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
  add_kernel_option(app, o.kernel);
}

void add_kernel_option(CLI::App& app, std::string& kernel) {
  app.add_option("--kernel", kernel,
                 "Reconstruction of volumes: bspline (approximating, C2), catmull-rom (interpolating, C1), "
                 "mix (Catmull-Rom value, B-spline derivatives)")
      ->capture_default_str();
}

VolumeFieldParams kernel_params(const std::string& kernel) {
  if (kernel == "bspline") return {KernelType::bspline, KernelType::bspline};
  if (kernel == "catmull-rom") return {KernelType::catmull_rom, KernelType::catmull_rom};
  if (kernel == "mix") return VolumeFieldParams::chapter5_mix();
  throw UsageError("--kernel \"" + kernel + "\" is unknown; expected bspline, catmull-rom or mix");
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
  const VolumeFieldParams vp = kernel_params(o.kernel);
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
