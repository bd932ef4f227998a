#pragma once
// Command-line options shared by tools that read a scalar field: a volume
// (`-i FILE --iso C --kernel K`) or an analytic implicit (`--implicit SPEC`).
#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "pm/base/volume.h"
#include "pm/field/field.h"
#include "pm/field/volume_field.h"

namespace pm {

struct FieldOptions {
  std::string input;      ///< volume file
  std::string implicit;   ///< analytic implicit spec
  std::string kernel = "bspline";  ///< bspline | catmull-rom | mix
  double iso = 0;
};

/// Adds -i/--input, --implicit, --iso, --kernel to `app`.
void add_field_options(CLI::App& app, FieldOptions& o);

/// Adds only --kernel (for tools that read a volume themselves, e.g. mcinit).
void add_kernel_option(CLI::App& app, std::string& kernel);

/// The reconstruction of a --kernel name: bspline, catmull-rom or mix
/// (Catmull-Rom value, B-spline derivatives). \throw UsageError otherwise.
VolumeFieldParams kernel_params(const std::string& kernel);

struct LoadedField {
  std::unique_ptr<ScalarField> field;
  double iso = 0;
  bool from_volume = false;
  ValueRange range;  ///< voxel value range (volumes only)
};

/// Build the field. \throw UsageError when neither or both of --input and
/// --implicit are given or the kernel is unknown; InputError (via the readers)
/// for bad files, NaN voxels, and an isovalue outside the volume's value range.
LoadedField load_field(const FieldOptions& o);

}  // namespace pm
