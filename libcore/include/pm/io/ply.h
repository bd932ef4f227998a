#pragma once
// PLY (Stanford polygon format), hand-written: CGAL's PLY IO cannot carry
// arbitrary named vertex scalars and per-face int properties on a
// non-manifold polygon soup.
#include <string>
#include <vector>

#include "pm/base/mesh.h"
#include "pm/io/frame.h"

namespace pm {

/// Read ASCII or binary (little or big endian) PLY: vertex properties x y z,
/// optional nx ny nz and any other scalar property; face vertex_indices (or
/// vertex_index) lists, fan-triangulated, and integer face properties. Every
/// PLY scalar type is accepted; elements other than vertex and face are
/// skipped. Coordinates are returned as stored; `frame` (when not null) is set
/// from a `comment frame RAS` / `SPACE=RAS` line (LPS when none says so).
/// \throw IoError when unreadable, InputError naming the file, the record and
/// the expectation on malformed content.
/// `polygon_sizes` (when not null) receives each face's vertex count, in
/// order: face k became its n - 2 fan triangles (pm::fans_to_polygons).
Mesh read_ply(const std::string& path, WorldFrame* frame = nullptr, std::vector<int>* polygon_sizes = nullptr);

/// Write PLY to `path` directly (no atomic rename: write_mesh does that):
/// positions, normals and vertex scalars as float, face properties as int, and
/// a `comment frame LPS SPACE=LPS` (or RAS) line stating the frame the
/// coordinates are in (they are written as given).
/// `binary` asks for binary little endian; a mesh with face properties is
/// written as ASCII all the same, because meshio's binary PLY reader (Debian's
/// python3-meshio 5 to 7) reads the properties of the face element column by
/// column instead of record by record and fails (IndexError) on them.
/// `doubles` writes the vertex properties (positions, normals, scalars) as
/// double instead: float rounds to ~6e-8 relative, far above the accuracy of
/// Newton-projected particles on high-order fields (Chapter 4 wants 1e-10).
/// \throw InputError when the mesh fails validate() or a property name is not
/// one printable word or clashes with x y z, nx ny nz or vertex_indices;
/// IoError when the file cannot be written.
void write_ply(const Mesh& m, const std::string& path, bool binary = true, WorldFrame frame = WorldFrame::lps,
               bool doubles = false);

/// The name checks of write_ply, on their own (write_mesh runs them before
/// it creates any file).
void check_ply_names(const Mesh& m, const std::string& where);

}  // namespace pm
