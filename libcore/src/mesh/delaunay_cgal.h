// Internal to libcore's mesh concern: the parallel Delaunay tetrahedralisation
// behind pm::delaunay (CGAL with TBB), defined in its own translation unit.
#pragma once

#include <cstddef>
#include <vector>

#include "pm/base/vec.h"
#include "pm/mesh/tetlabel.h"

namespace pm {

/// Delaunay tetrahedra of `points` with CGAL's parallel triangulation: out
/// gets positively oriented tetrahedra in a canonical order (independent of
/// the thread count), neighbour i opposite corner i, -1 on the hull.
/// `vertices` receives the triangulation's vertex count: fewer than the
/// points when some coincide (out is then left empty). Returns false when
/// CGAL was built without TBB (the caller uses TetGen).
bool parallel_delaunay(const std::vector<Vec3>& points, TetMesh& out, std::size_t& vertices);

}  // namespace pm
