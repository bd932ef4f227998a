#pragma once
// The reference-space seam of SPEC §4: a field given per element as F*(xi)
// on a reference element, with an element map T(xi) = x. Particles in
// reference space (pm/sample/hp_constraint.h) run on this interface; it is
// implemented by Nektar++ fields (pm/field/hp_field.h) and by the analytic
// B-spline-mapped teardrop (pm/field/teardrop.h).
//
// Reference elements use Nektar++'s conventions: xi in [-1,1]^3; the
// tetrahedron is xi_i >= -1, xi1 + xi2 + xi3 <= -1. Local faces:
//   tetrahedron  0: xi3 = -1   1: xi2 = -1   2: xi1+xi2+xi3 = -1   3: xi1 = -1
//   hexahedron   0: xi3 = -1   1: xi2 = -1   2: xi1 = +1   3: xi2 = +1
//                4: xi1 = -1   5: xi3 = +1
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "pm/base/vec.h"
#include "pm/io/nektar.h"

namespace pm {

/// A point in an element's reference space: element index (0..num_elements)
/// and reference coordinates xi.
struct RefPoint {
  int elem = -1;  ///< -1: no element (outside the mesh)
  Vec3 xi;
};

/// Everything a reference-space constraint needs at one point.
struct HpSample {
  Vec3 x;         ///< world position T(xi), world units
  Mat3 J;         ///< dT/dxi: J[a][i] = d x_a / d xi_i
  Mat3 K;         ///< J^-1
  double f = 0;   ///< F*(xi)
  Vec3 grad_ref;  ///< grad_xi F*
  Mat3 hess_ref;  ///< Hessian of F* in xi
  Vec3 grad;      ///< world gradient K^T grad_xi F*
  Mat3 hess;      ///< world Hessian K^T (H* - sum_a grad_a d2T^a) K
};

class ReferenceField {
 public:
  virtual ~ReferenceField() = default;
  virtual int num_elements() const = 0;
  virtual NektarShape shape(int elem) const = 0;
  /// The element's id as written to outputs (Nektar++ id, or the index).
  virtual int element_id(int elem) const = 0;
  /// Polynomial modes per direction (order + 1); seeding uses at least this many lattice points.
  virtual std::array<int, 3> modes(int elem) const = 0;
  /// World positions of the element's vertices in local order (4 or 8).
  virtual std::vector<Vec3> element_vertices(int elem) const = 0;
  /// F*(xi): one field evaluation.
  virtual double ref_value(int elem, const Vec3& xi) const = 0;
  /// One field and one map evaluation.
  virtual HpSample sample(int elem, const Vec3& xi) const = 0;
  /// The local face whose plane xi is farthest beyond (by more than tol), -1 when inside.
  virtual int exit_face(int elem, const Vec3& xi, double tol = 0) const = 0;
  /// Closest point of the reference element to xi.
  virtual Vec3 clamp_to_element(int elem, const Vec3& xi) const = 0;
  /// Preimage of world x under element elem's map (also outside the element); false when Newton fails.
  virtual bool inverse_map(int elem, const Vec3& x, Vec3& xi) const = 0;
  /// World point -> element + reference coordinates (elem = -1 outside); hint: an element to try first.
  virtual RefPoint locate(const Vec3& x, int hint = -1) const = 0;
  /// A point xi of elem that has left it through local face `face`: the same
  /// point in the neighbour's reference space (elem = -1 on the boundary).
  virtual RefPoint cross_face(int elem, int face, const Vec3& xi) const = 0;
  virtual Box domain() const = 0;       ///< world bounding box
  virtual double resolution() const = 0;  ///< finest polynomial scale, world units
  virtual std::string describe() const = 0;
  virtual std::uint64_t field_evaluations() const = 0;  ///< forward evaluations of F* so far
  virtual std::uint64_t map_evaluations() const = 0;    ///< forward evaluations of T so far
};

}  // namespace pm
