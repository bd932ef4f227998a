#pragma once
// Baseline surface meshers to compare the particle meshes against (issue 5,
// "Baselines side by side"): marching cubes on the same volume (OpenVDB
// volumeToMesh) and CGAL Mesh_3 on the grey-level isosurface or on a label
// map (with its triple lines protected). World units from the volume header.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "pm/base/volume.h"
#include "pm/io/mesh.h"
#include "pm/io/tet_mesh.h"
#include "pm/mesh/tet_conform.h"

namespace pm {

/// Marching cubes (OpenVDB volumeToMesh, adaptivity 0) of F = iso, F the
/// trilinear interpolation of the voxels. `material_below`: the material is
/// F < iso (distance fields) rather than F > iso (masks, CT). Outside the
/// volume counts as outside the material, so surfaces cut by the volume's
/// border are closed there. Quads are split along their shorter diagonal;
/// faces are oriented outward (normals point out of the material).
/// \throw InputError when the volume is not axis-aligned (OpenVDB needs an
/// affine map, which we have; kept general) or no voxel is on each side.
Mesh marching_cubes_baseline(const Volume& v, double iso, bool material_below);

/// Total area of a triangle mesh, world units squared.
double mesh_area(const Mesh& m);

struct CgalMeshParams {
  double facet_size = 0;      ///< Mesh_3 facet_size (surface Delaunay ball radius bound), world units, > 0
  double facet_distance = 0;  ///< Mesh_3 facet_distance, world units (0: facet_size / 4)
  double facet_angle = 30;    ///< Mesh_3 facet_angle lower bound, degrees
  double edge_size = 0;       ///< labels: size of the protected triple lines' edges (0: facet_size)
  int threads = 0;            ///< 0: all cores (CGAL's parallel Mesh_3 needs TBB; > 1 is not deterministic)
  std::uint64_t seed = 1;     ///< CGAL's default random generator
  /// Volume mesh (issue #19's side by side): refine the cells too
  /// (cell_radius_edge_ratio, cell_size), keep the labelled tetrahedra in
  /// CgalMeshResult::volume, and with `optimise` run CGAL's sliver
  /// perturbation (perturb_mesh_3) and then sliver exudation (exude_mesh_3),
  /// each measured as its own step.
  bool volume = false;
  /// Labels: the outside (not meshed; 0 in the output's label pairs stays
  /// this label). -1: the label at most of the volume's 8 corners.
  int outside_label = -1;
  double cell_radius_edge = 2;  ///< circumradius / shortest edge bound (CGAL guarantees termination for >= 2)
  double cell_size = 0;         ///< circumradius bound, world units (0: none, the cells grade away from the surface)
  bool optimise = true;         ///< volume: perturb, then exude
  double optimise_seconds = 0;  ///< time limit of perturb and of exude, each (0: none)
};

struct CgalMeshResult {
  Mesh surface;               ///< boundary facets of the c3t3 (labels: every interface)
  std::size_t c3t3_vertices = 0;
  double seconds = 0;         ///< time in CGAL (domain + make_mesh_3 + extraction)
  bool parallel = false;
  /// CgalMeshParams::volume: the cells in the complex (materials = subdomain
  /// indices, 1 for an isosurface's material, the labels for a label map;
  /// positively oriented) and the complex's facets with their label pairs
  /// (0 = outside), and one measured step per pass: "refine" (make_mesh_3),
  /// "perturb", "exude".
  LabelledTets volume;
  std::vector<ConformStep> steps;
  /// Vertices the size search counts: the tetrahedra's with `volume`, else the surface's.
  std::size_t vertex_count() const { return volume.tets.empty() ? surface.vertices.size() : volume.vertices.size(); }
};

/// CGAL Mesh_3 surface mesh of the isosurface F = iso of a grey-level image
/// (trilinear values, make_mesh_3 with facet criteria only, manifold option,
/// no perturbation/exudation). Output: the boundary facets, oriented outward.
/// \throw InputError for a non axis-aligned volume, no surface found;
/// UsageError for bad sizes.
CgalMeshResult cgal_isosurface(const Volume& v, double iso, bool material_below, const CgalMeshParams& p);

/// CGAL Mesh_3 on a label map (Labeled_mesh_domain_3 with polyline features):
/// the lines where three or more labels meet (triple_lines below) are
/// protected. The outside label (p.outside_label, by default the label at
/// most corners; e.g. mickey's background 1) is not meshed. Output: every
/// facet between two different labels, the outside label included, with face
/// ints label_a < label_b, oriented from label_a to label_b.
/// \throw InputError for a non-integer or non axis-aligned volume, a single label.
CgalMeshResult cgal_labels(const Volume& labels, const CgalMeshParams& p);

/// Lines where three or more labels meet in a label map, as polylines in world
/// units on the dual grid: a node at the centre of every 2x2 voxel square with
/// at least three labels, joined through the 2x2x2 voxel cubes that contain
/// them (directly when a cube holds two such squares, through the cube centre
/// otherwise). Polylines meet only at their end points; a closed loop repeats
/// its first point at the end.
std::vector<std::vector<Vec3>> triple_lines(const Volume& labels);

/// Facet size that should give about `vertices` vertices on a surface of
/// `area` (world units^2): hexagonal sampling with Mesh_3's typical edge
/// length ~ 1.2 facet_size. A starting value for a search.
double facet_size_for_vertices(double area, std::size_t vertices);

/// Area of the interfaces of a label map, world units^2: 2/3 of the area of
/// the voxel faces between two different labels (a staircase overestimates a
/// smooth surface by about 3/2). \throw InputError (naming `what`) when the
/// map holds a single label.
double label_interface_area(const Volume& labels, const std::string& what);

struct SizeSearchParams {
  std::size_t target = 0;   ///< vertices wanted (0: one run at the given facet size)
  double start_size = 0;    ///< first facet size tried, world units (e.g. facet_size_for_vertices)
  double tolerance = 0.1;   ///< accepted relative deviation of the vertex count
  int max_runs = 5;         ///< most Mesh_3 runs
  /// N ~ size^-1/exponent: 0.5 for surfaces; volumes graded from the
  /// surface grow faster than surfaces as the size shrinks (about 0.4).
  double exponent = 0.5;
};

struct SizeSearchTry {
  double facet_size = 0;
  std::size_t vertices = 0;
  double seconds = 0;
};

struct SizeSearchResult {
  CgalMeshResult best;             ///< the run closest to the target
  double facet_size = 0;           ///< its facet size, world units
  double deviation = 0;            ///< |vertices / target - 1| of the best run
  std::vector<SizeSearchTry> tries;
};

/// Run `mesher` at p.facet_size (target 0), or search the facet size whose
/// mesh has about `target` vertices (CgalMeshResult::vertex_count): N ~
/// 1/size^2 on a surface, so size *= (N / target)^exponent after the first
/// run; after that the exponent is the log-log secant of the last two runs
/// (within 0.5-4x the model's), until within the tolerance or max_runs. A given
/// facet_distance stays fixed; by default it is facet_size / 4 at every size.
/// Volume meshes with optimisation: the tries skip it, and the best size is
/// run once more with it (perturbation and exudation add no vertices).
using CgalMesher = std::function<CgalMeshResult(const CgalMeshParams&)>;
SizeSearchResult cgal_size_search(const CgalMesher& mesher, CgalMeshParams p, const SizeSearchParams& s);

}  // namespace pm
