#pragma once
// Gmsh MSH 4.1 ASCII (what Gmsh 4 writes by default, and meshio and
// FEniCS/dolfinx read): one volume entity and one physical volume group per
// material, named "material_<label>".
#include <string>

#include "pm/io/frame.h"
#include "pm/io/tet_mesh.h"

namespace pm {

/// Nodes (tags 1..#V, in the first material's entity), tetrahedra (element
/// type 4) in one block per material. Physical tags are the material labels
/// when every label is positive, else 1, 2, ... in ascending label order (Gmsh
/// wants positive tags); the names always carry the label. The frame is
/// stated in a $Comments section. Writes to `path` directly (no atomic rename).
/// \throw InputError when `t` fails validate() or has no tetrahedra; IoError
/// when the file cannot be written.
void write_gmsh(const LabelledTets& t, const std::string& path, WorldFrame frame = WorldFrame::lps);

}  // namespace pm
