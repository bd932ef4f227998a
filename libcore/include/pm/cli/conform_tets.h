#pragma once
// The `tetlabel --conform` run (issue #19): read a closed surface (one
// material) or an interface mesh (several), the interior points and the
// field or material set that labels the volume; mesh with
// pm::conforming_tets; write the labelled tetrahedra and the per-step
// quality into pm::stats(). World units throughout.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "pm/cli/field_options.h"
#include "pm/cli/material_options.h"
#include "pm/io/frame.h"
#include "pm/mesh/tet_conform.h"

namespace pm {

struct ConformRun {
  std::string interior;  ///< interior points (any read_mesh format; vertices only)
  std::string surface;   ///< boundary: a closed surface, or interfaces with face properties label_a < label_b
  std::vector<std::string> tets;  ///< outputs, one per format, by extension (write_tet_mesh)
  /// One material: the field and its isovalue (material on the `inside` side
  /// of iso: "below", "above" or "auto"); every triangle gets labels (0, 1).
  FieldOptions field;
  std::string inside = "auto";
  /// Several materials (materials.spec non-empty): label_at = the material
  /// with the largest indicator; `outside` is an integer label or "auto".
  MaterialOptions materials;
  std::string outside = "auto";
  ConformParams params;
  std::string require;  ///< pm::check_tet_requirements items on the final mesh ("" = none)
  WorldFrame frame = WorldFrame::lps;
};

/// Adds --conform SURFACE, --min-dihedral, --radius-edge, --max-dihedral,
/// --optimise/--no-optimise and --require (all into `r`) to `app`.
void add_conform_options(CLI::App& app, ConformRun& r);

/// Validate the options that cost no work (output extension, requirement
/// names). \throw UsageError.
void check_conform_options(const ConformRun& r);

/// Run it: stats() gets inputs, parameters, counts, steps, quality, outputs.
/// \throw UsageError (options), InputError/IoError (files, meshing), and
/// CheckFailed after writing when a --require item fails.
void run_conform(const ConformRun& r);

}  // namespace pm
