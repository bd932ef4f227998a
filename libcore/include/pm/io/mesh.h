#pragma once
// Reading and writing meshes and point sets (the Mesh type: pm/base/mesh.h),
// choosing the format by extension from one table (mesh.cpp):
//   .ply   PLY, every property                                   read + write
//   .vtp   VTK XML PolyData, every property as point/cell data    write
//   .vtk   VTK legacy POLYDATA, every property                    read + write
//   .mesh  MEDIT, triangle references for label pairs             read + write
//   .obj .off .stl  geometry only (CGAL)                          read + write
// Coordinates inside libcore are in the LPS world frame (pm/io/frame.h);
// write_mesh converts them into the frame asked for and says so in the file
// where the format can (PLY, VTK, MEDIT, OBJ comments), read_mesh converts
// back from the frame a file states.
#include <string>

#include "pm/base/mesh.h"
#include "pm/io/frame.h"

namespace pm {

struct MeshWriteParams {
  bool binary = true;                  ///< PLY/STL/VTK legacy: binary (default) or ASCII (see write_ply)
  WorldFrame frame = WorldFrame::lps;  ///< frame of the coordinates in the file
};

/// Read by extension (.ply .vtk .mesh .obj .off .stl), into the LPS frame.
/// \throw IoError, InputError naming the file, the problem and the expectation;
/// UsageError for an extension that is not read.
Mesh read_mesh(const std::string& path);

/// Write by extension (.ply .vtp .vtk .mesh .obj .off .stl); atomic
/// (temporary file + rename).
/// \throw UsageError for another extension, InputError when the mesh fails
/// validate() or cannot be stored in the format (property names, STL without
/// faces), IoError when the file cannot be written.
void write_mesh(const Mesh& m, const std::string& path, const MeshWriteParams& p = {});

/// True if write_mesh knows the extension; `points`: and the format keeps a
/// point set with its vertex scalars (.ply .vtp .vtk).
bool is_mesh_path(const std::string& path, bool points = false);
/// The extensions write_mesh knows (or those that keep point sets), for
/// messages and help texts: ".ply .vtp .vtk .mesh .obj .off .stl".
std::string mesh_extensions(bool points = false);

}  // namespace pm
