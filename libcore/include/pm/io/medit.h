#pragma once
// MEDIT `.mesh` (INRIA's ASCII mesh format, as Gmsh, TetGen, CGAL and meshio
// read it): Vertices, Triangles and Tetrahedra, each with an integer reference.
// Triangle references stand for label pairs: reference k (1-based) is the
// k-th distinct (label_a, label_b) pair in ascending order, listed in comment
// lines `# triangle reference k: label_a A label_b B` that read_medit turns
// back into the face properties. The frame is stated in a comment
// `# frame LPS SPACE=LPS`. Writers write to `path` directly (no atomic rename)
// and take coordinates as given.
#include <string>

#include "pm/base/mesh.h"
#include "pm/io/frame.h"
#include "pm/io/tet_mesh.h"

namespace pm {

/// Surface: Vertices (reference 0) and Triangles. A triangle's reference is
/// its label pair's number when the mesh has face properties label_a and
/// label_b, else its face property `ref`, else 0. Other properties and
/// normals are not stored.
/// \throw InputError when the mesh fails validate(); IoError when the file
/// cannot be written.
void write_medit(const Mesh& m, const std::string& path, WorldFrame frame = WorldFrame::lps);

/// Reads Vertices and Triangles (other sections are skipped; Quadrilaterals
/// are split in two). Triangle references become the face property `ref`, and
/// label_a / label_b / pair too when the pair comments are there.
/// \throw IoError when unreadable; InputError for malformed content, naming
/// the section and record.
Mesh read_medit(const std::string& path, WorldFrame* frame = nullptr);

/// Volume: Vertices, the boundary and interface Triangles (label pairs as
/// above) and the Tetrahedra with their material as reference.
void write_medit_tets(const LabelledTets& t, const std::string& path, WorldFrame frame = WorldFrame::lps);

}  // namespace pm
