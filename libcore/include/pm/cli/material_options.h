#pragma once
// Command-line option shared by the Chapter-6 tools that read a material set
// (pm/field/materials.h): `--materials SPEC` and its reconstruction kernel.
#include <CLI/CLI.hpp>
#include <string>

#include "pm/field/materials.h"

namespace pm {

struct MaterialOptions {
  std::string spec;                    ///< "" = not given
  std::string kernel = "catmull-rom";  ///< bspline | catmull-rom
};

/// Help text for --materials (shared so every tool says the same).
std::string materials_help();

/// Adds --materials SPEC (required when `required`) and, when `kernel_option`
/// names one (e.g. "--material-kernel"; "" = none), a kernel option to `app`.
CLI::Option* add_material_options(CLI::App& app, MaterialOptions& o, bool required = true,
                                  const std::string& kernel_option = "--material-kernel");

/// Parse the kernel name. \throw UsageError for an unknown one.
Kernel parse_kernel(const std::string& name);

/// --outside: "auto" (pm::auto_outside_label, the material touching the
/// volume's border) or an integer label. \throw UsageError otherwise.
int parse_outside_label(const std::string& s, const MaterialSet& ms);

/// load_materials(o.spec, parse_kernel(o.kernel)).
/// \throw UsageError when the spec is empty, plus whatever load_materials throws.
MaterialSet load_materials(const MaterialOptions& o);

}  // namespace pm
