#pragma once
// Reading VTK XML UnstructuredGrid (.vtu) files as tetrahedral meshes: what
// write_vtu (pm/io/vtk.h) writes, meshio's defaults (base64 binary arrays,
// zlib-compressed) and ParaView's (appended raw or base64 data).
#include <string>

#include "pm/io/frame.h"
#include "pm/io/tet_mesh.h"

namespace pm {

/// Reads every Piece (vertex indices offset piece by piece). DataArray
/// formats ascii, binary (base64) and appended (raw or base64 encoding);
/// header_type UInt32 (the default) or UInt64; no compressor or
/// vtkZLibDataCompressor; either byte order. Cells as for read_vtk_tets:
/// tetrahedra and triangles kept, other 0-D to 2-D cells skipped. Material:
/// the one-component cell array `material`, else `gmsh:physical`, else
/// `medit:ref` (0 without any); triangles' label pairs from `label_a` and
/// `label_b`, else (0, material). `frame` (when not null) is set from an XML
/// comment or a FieldData string array SPACE stating RAS or LPS (LPS when
/// none). The result may have no tetrahedra.
/// \throw IoError when unreadable; InputError for other XML files, other
/// compressors (LZ4, LZMA), 3-D cells other than tetrahedra, and malformed or
/// truncated content, naming the element, its XML line and the array.
LabelledTets read_vtu(const std::string& path, WorldFrame* frame = nullptr);

}  // namespace pm
