#pragma once
// Labelled tetrahedral meshes for writing: the tetrahedra of some materials
// plus the triangles that bound them, in the formats finite-element and
// visualisation tools read. Format by extension (one table, tet_mesh.cpp):
//   .mesh  MEDIT (Vertices, Triangles with a reference per label pair,
//          Tetrahedra with the material as reference)
//   .vtu   VTK XML UnstructuredGrid, cell array `material` (tetrahedra only)
//   .vtk   VTK legacy UNSTRUCTURED_GRID, cell scalars `material` (tetrahedra only)
//   .msh   Gmsh 4.1 ASCII, one physical volume group per material
//          ("material_L") and one physical surface group of triangles per
//          label pair ("interface_A_B")
// read_tet_mesh reads the same extensions, including what other tools write
// there (meshio, Gmsh, ParaView; see each format's reader for the variants).
#include <array>
#include <string>
#include <vector>

#include "pm/base/vec.h"
#include "pm/io/frame.h"

namespace pm {

struct LabelledTets {
  std::vector<Vec3> vertices;                   ///< #V, world units (LPS)
  std::vector<std::array<int, 4>> tets;         ///< #T vertex indices, positively oriented
  std::vector<int> materials;                   ///< #T material label of each tetrahedron
  std::vector<std::array<int, 3>> triangles;    ///< #B boundary and interface triangles
  /// #B (label_a, label_b), label_a < label_b: the labels on the two sides of
  /// each triangle (the outside label for a boundary triangle).
  std::vector<std::array<int, 2>> triangle_labels;

  /// \throw InputError when sizes disagree or an index is out of range.
  void validate(const std::string& what) const;
};

struct TetWriteParams {
  WorldFrame frame = WorldFrame::lps;  ///< coordinates are converted into it and the file says so
  bool binary = false;                 ///< .vtk only: BINARY instead of ASCII
};

/// Extensions write_tet_mesh knows, for messages: ".mesh .vtu .vtk .msh".
std::string tet_mesh_extensions();
/// True if write_tet_mesh knows the extension of `path`.
bool is_tet_mesh_path(const std::string& path);

/// Read a labelled tetrahedral mesh by extension (.mesh .vtu .vtk .msh) into
/// the LPS frame: a file that states RAS (SPACE=RAS, "frame RAS") has x and y
/// negated back. Tetrahedra keep the file's vertex order (no reorientation).
/// Materials: MEDIT references; the VTK cell array `material` (else
/// `gmsh:physical`, else `medit:ref`; 0 without any); Gmsh physical tags.
/// Triangles with their label pairs where the file has them (see each reader).
/// \throw UsageError for another extension; IoError when unreadable;
/// InputError naming the file and the line, section or element for malformed
/// or truncated content, and when the file holds no tetrahedra.
LabelledTets read_tet_mesh(const std::string& path);

/// True when `path` has a tetrahedral extension and holds at least one
/// tetrahedron; false for other files, surfaces, and files the tetrahedral
/// reader cannot parse (read_tet_mesh then says why). Reads the whole file
/// for .vtu .vtk .msh, scans it for .mesh.
bool file_has_tetrahedra(const std::string& path);

/// Whether read_tet_mesh (rather than a surface reader) is the reader for
/// `path`: .vtu and .msh always (nothing else here reads them), .mesh and
/// .vtk when file_has_tetrahedra (else they are surfaces for read_mesh), and
/// a legacy UNSTRUCTURED_GRID .vtk that neither reader can read (a truncated
/// tetrahedral file: read_tet_mesh's message names the line).
bool is_tet_mesh_file(const std::string& path);

/// Write by extension, atomically (temporary file + rename).
/// \throw UsageError for another extension, InputError when `t` fails
/// validate(), IoError when the file cannot be written.
void write_tet_mesh(const LabelledTets& t, const std::string& path, const TetWriteParams& p = {});

}  // namespace pm
