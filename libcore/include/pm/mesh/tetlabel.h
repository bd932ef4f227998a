#pragma once
// Meshing by labelled Delaunay tetrahedra (SPEC §5 "Triangulation", §6.4.3):
// tetrahedralise the particles with TetGen, label every tetrahedron with the
// material at its circumcentre, and keep the faces between differently
// labelled tetrahedra. Works for one material (inside/outside) and many.
#include <array>
#include <functional>
#include <string>
#include <vector>

#include "pm/base/vec.h"
#include "pm/io/mesh.h"
#include "pm/mesh/topology.h"
#include "pm/io/tet_mesh.h"

namespace pm {

/// A Delaunay tetrahedralisation with per-tetrahedron labels.
struct TetMesh {
  std::vector<Vec3> points;                   ///< #P, world units (input order)
  std::vector<std::array<int, 4>> tets;       ///< #T, positively oriented
  std::vector<std::array<int, 4>> neighbours; ///< #T; neighbour i is opposite corner i; -1 = hull
  std::vector<int> labels;                    ///< #T after label_tets
};

/// What a TetGen failure code (the int TetGen throws) means, e.g. 3 ->
/// "self-intersection in input"; "" for a code it does not name.
std::string tetgen_failure(int code);

/// Delaunay tetrahedralisation of `points`: CGAL's parallel triangulation
/// (when CGAL has TBB; tetrahedra in a canonical order, the same for any
/// thread count), else TetGen's.
/// \throw InputError when there are fewer than 4 points, non-finite points,
/// coinciding points, all points are coplanar, or TetGen fails (its error
/// code is named).
TetMesh delaunay(const std::vector<Vec3>& points);

/// The same with TetGen (switches "zQn"), tetrahedra in TetGen's order.
TetMesh tetgen_delaunay(const std::vector<Vec3>& points);

/// delaunay() of `points` plus the 8 corners of a box around them (enlarged
/// by their bounding-box diagonal on every side); tetrahedra with a corner
/// are dropped, so their faces become hull faces (neighbour -1) and
/// `points` keeps only the input points. No input point lies on the convex
/// hull then: a flat patch of the surface (a mask cut by the volume border)
/// is not a hull facet, whose coplanar points TetGen would join by slivers
/// up to the far end of the hull.
TetMesh delaunay_enclosed(const std::vector<Vec3>& points);

/// Material label at a world point (e.g. 1 inside, 0 outside; or argmax f_i).
using LabelFunction = std::function<int(const Vec3&)>;

struct TetLabelParams {
  /// A tetrahedron whose normalised volume 6√2·V / l_rms³ (1 for a regular
  /// tetrahedron, 0 for a flat one) is below this is degenerate: four
  /// co-circular points, whose circumcentre is numerically meaningless. It
  /// takes the majority label of its face neighbours (in exact arithmetic it
  /// shares their circumsphere); a tie is decided at its centroid. Keep this
  /// near rounding level: nearly-flat but genuine tetrahedra have meaningful
  /// circumcentres (tested on an exactly regular torus grid and jittered ones).
  double flat_quality = 1e-9;
};

struct TetLabelStats {
  std::size_t tets = 0;
  std::size_t flat = 0;  ///< degenerate, labelled from their neighbours
};

/// Label every tetrahedron by `label` at its circumcentre (centroid for flat ones).
/// `label` is called from several threads at once (it must only read).
TetLabelStats label_tets(TetMesh& tm, const LabelFunction& label, const TetLabelParams& p = {});

/// The tetrahedra around every vertex, in ascending order (CSR: those of
/// vertex v are tets[start[v] .. start[v + 1])).
struct VertexTets {
  std::vector<int> start, tets;
  explicit VertexTets(const TetMesh& tm);
  const int* begin(int v) const { return tets.data() + start[std::size_t(v)]; }
  const int* end(int v) const { return tets.data() + start[std::size_t(v) + 1]; }
  bool empty(int v) const { return start[std::size_t(v)] == start[std::size_t(v) + 1]; }
};

/// Make the surface of material `label` a manifold: at every vertex where its
/// faces form more than one fan or an edge has more than two faces (a pinch
/// where the surface nearly touches itself, e.g. across a thin gap), relabel
/// tetrahedra around that vertex: first a single tetrahedron whose flip fixes
/// the vertex without breaking its neighbours, else every tetrahedron around
/// it joins the material (the vertex is then buried). Returns the number of
/// tetrahedra relabelled. A relabelled tetrahedron leaving the material takes
/// the most common other label among its face neighbours.
std::size_t make_manifold(TetMesh& tm, int label, int outside_label);

/// Every face between two differently labelled tetrahedra; hull faces border
/// `outside_label`. Face properties `label_a`, `label_b` (label_a < label_b),
/// oriented so the normal points from label_a into label_b. Vertices are the
/// points used by some face (renumbered); vertex scalar `index` keeps the
/// original point index.
Mesh interface_mesh(const TetMesh& tm, int outside_label);

/// The closed surface of one material: faces between `label` and anything
/// else, oriented outward (normal points out of the material).
Mesh material_surface(const TetMesh& tm, int label, int outside_label);

/// The tetrahedra whose label differs from `outside_label`, for
/// write_tet_mesh: their points (renumbered in order of first use), their
/// labels as materials, and the faces of interface_mesh() (boundary and
/// interface triangles, oriented from label_a into label_b) with their labels.
LabelledTets labelled_tets(const TetMesh& tm, int outside_label);


}  // namespace pm
