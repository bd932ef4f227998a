#pragma once
// The one check every tool runs on each output option right after parsing,
// before any input is opened: the extension must name a format the writer of
// that kind of output knows. An unknown extension is a usage error (exit 2)
// that costs no work and leaves no file behind.
#include <string>

namespace pm {

enum class OutputKind {
  volume,    ///< write_volume: .nrrd .nhdr .vdb .mha .mhd .nii .nii.gz .inr .inr.gz
  mesh,      ///< write_mesh: .ply .vtp .vtk .mesh .obj .off .stl
  points,    ///< point sets with their scalars: .ply .vtp .vtk
  tet_mesh,  ///< write_tet_mesh: .mesh .vtu .vtk .msh
  poly_mesh, ///< write_poly_mesh (quads kept): .ply .obj .off
  png,       ///< .png
  json,      ///< .json, or "-" for stdout
};

/// \throw UsageError `--tets "v.obj": unknown tetrahedral mesh extension
/// ".obj"; expected .mesh .vtu .vtk .msh` (`option` names the option or the
/// positional argument, e.g. "--tets" or "output"). An empty path passes (an
/// option not given).
void check_output_path(const std::string& path, OutputKind kind, const std::string& option);

/// The extensions of a kind, for help texts: ".ply .vtp .vtk ...".
std::string output_extensions(OutputKind kind);

}  // namespace pm
