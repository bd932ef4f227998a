#pragma once
// VTK files, the formats ParaView and 3D Slicer open natively: legacy `.vtk`
// (POLYDATA or UNSTRUCTURED_GRID, version 4.2 as Slicer writes it) and XML
// `.vtp` (PolyData) and `.vtu` (UnstructuredGrid), ASCII data arrays.
// Face integer properties become Int32 cell data, vertex scalars Float64
// point data, normals the point data `Normals`, so viewers colour by them.
// The frame is stated the way Slicer reads it: `SPACE=LPS` (or RAS) in the
// legacy header line, a string field array `SPACE` in `.vtp`. `.vtu` states it
// in an XML comment only: meshio's VTU reader refuses string arrays, and
// Slicer takes a file without the field as LPS (right for the default frame;
// for RAS tetrahedra in Slicer, write `.vtk`).
// Writers write to `path` directly (no atomic rename: write_mesh and
// write_tet_mesh do that) and take coordinates as given.
#include <string>

#include "pm/base/mesh.h"
#include "pm/io/frame.h"
#include "pm/io/tet_mesh.h"

namespace pm {

/// Legacy UNSTRUCTURED_GRID of VTK_TRIANGLE cells (VTK_VERTEX for a point
/// set; meshio reads no legacy POLYDATA, ParaView and Slicer read both):
/// POINTS (double), CELLS, CELL_TYPES, CELL_DATA / POINT_DATA SCALARS and
/// the normals as VECTORS Normals (meshio reads no NORMALS section). ASCII,
/// or BINARY (big endian).
/// \throw InputError when the mesh fails validate() or a property name is not
/// one printable word; IoError when the file cannot be written.
void write_vtk(const Mesh& m, const std::string& path, bool binary = false, WorldFrame frame = WorldFrame::lps);

/// Reads what write_vtk writes and legacy POLYDATA (ASCII or BINARY, version
/// <= 4.2: POINTS; VERTICES and POLYGONS, or CELLS and CELL_TYPES of vertex,
/// triangle and polygon cells; polygons fan-triangulated; SCALARS, and NORMALS
/// or VECTORS Normals, point and
/// cell data; cell scalars become face ints, rounded). `frame` (when not null)
/// is set from a SPACE= in the header line (LPS when none).
/// \throw IoError when unreadable; InputError for other datasets, sections we
/// do not read, and malformed or truncated content, naming the section.
Mesh read_vtk(const std::string& path, WorldFrame* frame = nullptr);

/// XML PolyData, ASCII data arrays: Points (Float64), Polys (or Verts for a
/// point set), CellData and PointData as for write_vtk, FieldData `SPACE`.
void write_vtp(const Mesh& m, const std::string& path, WorldFrame frame = WorldFrame::lps);

/// Tetrahedra only (VTK_TETRA cells), cell scalars `material`; legacy
/// UNSTRUCTURED_GRID (ASCII or BINARY) or XML UnstructuredGrid.
void write_vtk_tets(const LabelledTets& t, const std::string& path, bool binary = false,
                    WorldFrame frame = WorldFrame::lps);
void write_vtu(const LabelledTets& t, const std::string& path, WorldFrame frame = WorldFrame::lps);

/// Reads a legacy UNSTRUCTURED_GRID as a tetrahedral mesh: versions up to 4.2
/// (CELLS n size) and 5.1 (OFFSETS/CONNECTIVITY, meshio's default), ASCII or
/// BINARY. Tetrahedra (VTK_TETRA; the corners of VTK_QUADRATIC_TETRA and
/// VTK_LAGRANGE_TETRAHEDRON) and triangles (likewise) are kept, 0-D to 2-D
/// cells of other kinds skipped. Material: the cell scalars or FIELD array
/// `material`, else `gmsh:physical`, else `medit:ref` (0 without any). A
/// triangle's label pair: cell arrays `label_a` and `label_b` when present,
/// else (0, its material value). `frame` (when not null) is set from a SPACE=
/// in the header line (LPS when none). The result may have no tetrahedra.
/// \throw IoError when unreadable; InputError for other datasets, 3-D cells
/// other than tetrahedra, non-integral materials, sections we do not know,
/// malformed or truncated content, naming the section, line and cell.
LabelledTets read_vtk_tets(const std::string& path, WorldFrame* frame = nullptr);

}  // namespace pm
