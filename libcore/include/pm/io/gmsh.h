#pragma once
// Gmsh MSH 4.1 ASCII (what Gmsh 4 writes by default, and meshio and
// FEniCS/dolfinx read): one volume entity and one physical volume group per
// material, named "material_<label>", and one surface entity and one physical
// surface group per label pair of the boundary and interface triangles, named
// "interface_<label_a>_<label_b>"; and a reader of MSH 4.1 and 2.2, ASCII and
// binary, as Gmsh and meshio write them.
#include <string>

#include "pm/io/frame.h"
#include "pm/io/tet_mesh.h"

namespace pm {

/// Nodes (tags 1..#V, in the first material's entity), tetrahedra (element
/// type 4, element tags 1..#T) in one block per material, then the triangles
/// (element type 2, element tags #T+1..#T+#B) in one block per distinct
/// (label_a, label_b) pair, in ascending order of each. Volume tags (entity
/// and physical tag alike) are the material labels when every label is
/// positive, else 1, 2, ... in ascending label order (Gmsh wants positive
/// tags); surface tags (entity and physical) go on from the largest volume tag
/// in ascending pair order, so no tag is both. The names always carry the
/// labels: "material_L", "interface_A_B" (A is the outside label for a
/// boundary triangle). $Entities gives each entity its bounding box and
/// physical tag, and lists no bounding curves or surfaces. The frame is stated
/// in a $Comments section. Writes to `path` directly (no atomic rename).
/// \throw InputError when `t` fails validate(), has no tetrahedra, or its
/// largest positive label leaves no room for the surface tags above it; IoError
/// when the file cannot be written.
void write_gmsh(const LabelledTets& t, const std::string& path, WorldFrame frame = WorldFrame::lps);

/// Reads MSH 4.1 and 2.2 (ASCII or binary, either byte order): nodes, and
/// of the elements the tetrahedra (linear; the corners of higher-order ones)
/// and triangles; points, lines and other surface elements are skipped.
/// A tetrahedron's material is its physical tag (4.1: the first physical tag
/// of its entity, the entity tag when the entity has none or there is no
/// $Entities section; 2.2: the first element tag), or L when that physical
/// group is named "material_L" (write_gmsh's names). A triangle's label pair
/// comes from a physical name ending in "_A_B" (e.g. write_gmsh's
/// "interface_1_2"; the smaller label first), else it is (0, physical tag).
/// `frame` (when not null) is set from a $Comments section stating SPACE=RAS /
/// SPACE=LPS (LPS when none). The result may have no tetrahedra.
/// \throw IoError when unreadable; InputError for other files (no
/// $MeshFormat; meshio's ANSYS .msh), other versions, 3-D elements that are not
/// tetrahedra, node tags that are not defined, and malformed or truncated
/// content, naming the section, the line and the element.
LabelledTets read_gmsh(const std::string& path, WorldFrame* frame = nullptr);

}  // namespace pm
