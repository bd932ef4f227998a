#pragma once
// The Chapter 4 baseline (issue #18): the isosurface of a high-order field
// as ParaView and Nektar++'s FieldConvert `isocontour` extract it. Each
// element is sampled on an equispaced lattice in its reference space, the
// lattice is split into tetrahedra and linear marching tetrahedra runs on
// the sampled values; world coordinates are interpolated linearly along the
// lattice edges, like the field.
#include <cstddef>
#include <cstdint>

#include "pm/field/hp_field.h"
#include "pm/base/mesh.h"

namespace pm {

struct LatticeIsoParams {
  /// Lattice points per element edge (>= 2). 0: FieldConvert's default, the
  /// number of quadrature points of the expansion, modes + 1.
  int points = 0;
  /// Weld vertices that coincide (shared lattice edges inside an element,
  /// and element faces shared by two elements, to 1e-12 of the mesh size).
  bool weld = true;
};

struct LatticeIsoResult {
  /// Triangles in world units, oriented with the normal towards increasing
  /// field values; vertex scalar "element" = Nektar++ id of the element
  /// the vertex came from.
  Mesh mesh;
  std::uint64_t field_evaluations = 0;  ///< lattice points evaluated (one each)
  std::size_t lattice_points = 0;       ///< summed over elements
  std::size_t lattice_tets = 0;         ///< summed over elements
};

/// Isosurface F = iso of `field` from an equispaced lattice per element and
/// linear marching tetrahedra. Hexahedron cells are split into 6
/// tetrahedra around their main diagonal; the tetrahedron lattice
/// (i + j + k <= n - 1) into (n - 1)^3 tetrahedra (Freudenthal).
/// \throw UsageError when params.points is 1 or negative.
LatticeIsoResult lattice_isosurface(const HpField& field, double iso, const LatticeIsoParams& params = {});

}  // namespace pm
