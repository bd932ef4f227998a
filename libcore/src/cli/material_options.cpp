#include "pm/cli/material_options.h"

#include "pm/base/error.h"
#include "pm/mesh/tetlabel_materials.h"

namespace pm {

std::string materials_help() {
  return "Materials: a label map (every label a material, label 0 included; each label's indicator is the "
         "signed distance of its mask) or \"L1=a.nrrd,L2=b.nrrd,...\", one volume per material, negative "
         "inside (signed distances, e.g. from tighten --per-label); \"L=+c.nrrd\" for a volume positive inside "
         "(indicator functions). Material at x = the largest indicator f_i = -d_i(x). World units from the headers";
}

CLI::Option* add_material_options(CLI::App& app, MaterialOptions& o, bool required, const std::string& kernel_option) {
  CLI::Option* opt = app.add_option("--materials", o.spec, materials_help());
  if (required) opt->required();
  if (!kernel_option.empty())
    app.add_option(kernel_option, o.kernel,
                   "Reconstruction of the material volumes: catmull-rom (interpolating, Chapter 6 default) or "
                   "bspline")
        ->capture_default_str()
        ->check(CLI::IsMember({"catmull-rom", "bspline"}));
  return opt;
}

Kernel parse_kernel(const std::string& name) {
  if (name == "catmull-rom") return KernelType::catmull_rom;
  if (name == "bspline") return KernelType::bspline;
  throw UsageError("kernel \"" + name + "\" is unknown; expected catmull-rom or bspline");
}

MaterialSet load_materials(const MaterialOptions& o) {
  if (o.spec.empty()) throw UsageError("--materials is empty; expected a label map or \"L1=a.nrrd,L2=b.nrrd,...\"");
  return load_materials(o.spec, parse_kernel(o.kernel));
}

int parse_outside_label(const std::string& s, const MaterialSet& ms) {
  if (s == "auto") return auto_outside_label(ms);
  try {
    std::size_t pos = 0;
    const int v = std::stoi(s, &pos);
    if (pos == s.size()) return v;
  } catch (const std::exception&) {
  }
  throw UsageError("--outside \"" + s + "\" is not an integer label or auto");
}

}  // namespace pm
