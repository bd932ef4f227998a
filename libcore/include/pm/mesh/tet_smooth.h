#pragma once
// Smoothing of the free vertices of a tetrahedral mesh (issue #19, "ODT or
// particle smoothing of interior vertices"): the optimal Delaunay
// triangulation update of Chen and Alliez et al., x_i <- sum_T |T| c_T /
// sum_T |T| over the tetrahedra T around vertex i (c_T the circumcentre),
// with the connectivity kept. A move is kept only when every tetrahedron
// around the vertex stays positively oriented, the worst radius ratio among
// them does not drop, and no dihedral angle among them goes below min(their
// old smallest, 25°) or above max(their old largest, 140°) (else half the
// move is tried, else none). So the mesh's smallest radius ratio and its
// extreme dihedral angles never get worse, and no vertex crosses a face:
// materials and boundary stay as they are. Then the free vertices of the
// remaining slivers are perturbed to raise their tetrahedra's worst angle
// margin (TetSmoothParams::perturb_below/above). World units.
#include <cstddef>

#include "pm/io/tet_mesh.h"

namespace pm {

struct TetSmoothParams {
  int sweeps = 5;              ///< Gauss-Seidel sweeps over the free vertices (>= 1)
  double stop_fraction = 1e-3; ///< stop early when fewer than this share of free vertices moved in a sweep
  /// Then sliver perturbation: the free vertices of tetrahedra with a
  /// dihedral angle below perturb_below or above perturb_above (degrees)
  /// move, by compass search, to raise min(smallest dihedral / perturb_below,
  /// (180° - largest) / (180° - perturb_above)) among their tetrahedra
  /// (0 and 180: none).
  double perturb_below = 15, perturb_above = 155;
};

struct TetSmoothResult {
  int sweeps = 0;               ///< sweeps run
  std::size_t moves = 0;        ///< accepted moves (full or half), all sweeps
  std::size_t rejected = 0;     ///< vertices left in place in a sweep because no move was acceptable
  std::size_t perturbed = 0;    ///< vertices the sliver perturbation moved
  std::size_t perturb_candidates = 0;  ///< free vertices of tetrahedra outside the perturbation band
  double odt_seconds = 0, perturb_seconds = 0;  ///< wall time of the two phases
};

/// Smooth the vertices with index >= first_free (the others, e.g. boundary
/// and interface vertices, never move). Deterministic for any thread count:
/// the free vertices are coloured so that no two of a colour share a
/// tetrahedron, and each colour moves in parallel, colour after colour.
/// \throw UsageError for sweeps < 1 or first_free beyond the vertices.
TetSmoothResult odt_smooth(LabelledTets& t, std::size_t first_free, const TetSmoothParams& p = {});

}  // namespace pm
