#pragma once
// High-order (spectral/hp) finite-element fields of Nektar++ (SPEC §4):
// per-element modal expansions in Nektar++'s modified bases, evaluated with
// value, gradient and Hessian in reference coordinates, the element maps
// T(xi) = x (straight-sided: affine tetrahedra, trilinear hexahedra), world
// derivatives, point location and the element adjacency through shared
// faces. HpField is also a ScalarField, so every world-space tool can sample
// it; reference-space constraints use the element-level calls.
//
// Reference elements are Nektar++'s (see pm/io/nektar.h): xi in [-1,1]^3;
// the tetrahedron is xi_i >= -1, xi1 + xi2 + xi3 <= -1. Local faces:
//   tetrahedron  0: xi3 = -1 (v0 v1 v2)   1: xi2 = -1 (v0 v1 v3)
//                2: xi1+xi2+xi3 = -1 (v1 v2 v3)   3: xi1 = -1 (v0 v2 v3)
//   hexahedron   0: xi3 = -1   1: xi2 = -1   2: xi1 = +1   3: xi2 = +1
//                4: xi1 = -1   5: xi3 = +1
// which is the element's face listing order in the mesh file.
//
// Bases (Nektar++ Basis.cpp / StdTetExp.cpp; z in [-1,1]):
//   Modified_A  psi_0 = (1-z)/2, psi_1 = (1+z)/2,
//               psi_p = (1-z)/2 (1+z)/2 P_{p-2}^{(1,1)}(z)  (p >= 2)
//   Modified_B  psi_{pq}: row p = 0 is Modified_A; row p >= 1:
//               ((1-z)/2)^p for q = 0, ((1-z)/2)^p (1+z)/2 P_{q-1}^{(2p-1,1)}(z)
//   Modified_C  psi_{pqr} = psi^B_{p+q, r}
// Hexahedron: u = sum c[i + P (j + Q k)] psi_i(xi1) psi_j(xi2) psi_k(xi3).
// Tetrahedron: collapsed coordinates eta1 = 2(1+xi1)/(-xi2-xi3) - 1,
//   eta2 = 2(1+xi2)/(1-xi3) - 1, eta3 = xi3; modes (p,q,r), r fastest, then
//   q, then p (p < P, q < Q-p, r < R-p-q); u = sum c_pqr psiA_p(eta1)
//   psiB_pq(eta2) psiC_pqr(eta3), with Nektar++'s singular-vertex treatment:
//   mode (0,0,1) is the whole top-vertex function (1+xi3)/2 and modes
//   (0,1,r) do not depend on eta1. The evaluator writes every basis function
//   as a product of homogeneous Jacobi polynomials in barycentric-type linear
//   functions of xi, which is the same polynomial with no division, so value,
//   gradient and Hessian are exact up to round-off everywhere, including on
//   the collapsed edge and vertex.
#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "pm/base/vec.h"
#include "pm/field/field.h"
#include "pm/io/nektar.h"
#include "pm/field/reference_field.h"

namespace pm {

struct HpFieldParams {
  /// Reference-space slack for "inside an element" in point location.
  double inside_tol = 1e-10;
  /// Newton iterations of the hexahedron inverse map.
  int newton_iterations = 40;
};

class HpField : public ScalarField, public ReferenceField {
 public:
  /// Field `variable` of `field` on `mesh`. Every mesh element needs
  /// coefficients. \throw InputError naming the files when an element of the
  /// field is not in the mesh (or has another shape), a mesh element has no
  /// coefficients, an element is curved (not supported yet: "element 3 has
  /// curved edge 17"), or an element is degenerate (J not invertible);
  /// UsageError when the variable does not exist.
  HpField(const NektarMesh& mesh, const NektarField& field, const std::string& variable, HpFieldParams params = {});

  // --- ScalarField (world space): locate, then evaluate. Outside the mesh
  // the nearest element is evaluated at its reference point closest to the
  // Newton/affine preimage clamped into the element (not to be relied on).
  double value(const Vec3& x) const override;
  double value_gradient(const Vec3& x, Vec3& grad) const override;
  double evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const override;
  Box domain() const override { return box_; }
  /// Smallest element edge / (modes - 1): the finest polynomial scale.
  double resolution() const override { return resolution_; }
  std::string describe() const override { return description_; }

  // --- elements
  int num_elements() const override { return static_cast<int>(elems_.size()); }
  NektarShape shape(int elem) const override { return elems_[elem].shape; }
  int element_id(int elem) const override { return elems_[elem].id; }  ///< Nektar++ element id
  int num_faces(int elem) const { return elems_[elem].shape == NektarShape::Tetrahedron ? 4 : 6; }
  std::array<int, 3> modes(int elem) const override { return elems_[elem].modes; }
  /// Element index of Nektar++ element id, -1 when absent.
  int element_index(int id) const;
  /// World positions of the element's vertices in local order (4 or 8).
  std::vector<Vec3> element_vertices(int elem) const override;
  /// Neighbour element across local face `face`, -1 on the boundary;
  /// *nb_face gets the neighbour's local face.
  int neighbour(int elem, int face, int* nb_face = nullptr) const;

  // --- reference space (the constraint seam). Each call of position /
  // jacobian / sample counts one map evaluation; each of ref_value /
  // ref_evaluate / sample one field evaluation.
  Vec3 position(int elem, const Vec3& xi) const;
  Mat3 jacobian(int elem, const Vec3& xi) const;
  /// d2T^a/dxi_i dxi_j for a = 0..2 (zero for tetrahedra).
  void map_hessians(int elem, const Vec3& xi, Mat3 d2T[3]) const;
  double ref_value(int elem, const Vec3& xi) const override;
  double ref_evaluate(int elem, const Vec3& xi, Vec3& grad_ref, Mat3& hess_ref) const;
  HpSample sample(int elem, const Vec3& xi) const override;

  /// True when xi is inside the reference element, up to `tol`.
  bool contains(int elem, const Vec3& xi, double tol = 0) const;
  /// The local face whose plane xi is farthest beyond (by more than tol), -1 when inside.
  int exit_face(int elem, const Vec3& xi, double tol = 0) const override;
  /// Closest point of the reference element to xi (in xi; tetrahedra: the
  /// Euclidean projection onto the reference simplex).
  Vec3 clamp_to_element(int elem, const Vec3& xi) const override;
  /// Preimage of world x under element elem's map (exact for tetrahedra,
  /// Newton for hexahedra, also outside the element). False when Newton
  /// does not converge.
  bool inverse_map(int elem, const Vec3& x, Vec3& xi) const override;
  /// World point -> element + reference coordinates; elem = -1 when x is in
  /// no element (up to params.inside_tol). `hint`: an element to try first
  /// (a walk through faces starts there).
  RefPoint locate(const Vec3& x, int hint = -1) const override;
  /// A point xi of elem that has left it through local face `face`: the
  /// same world point in the neighbour's reference space (elem = -1 on the
  /// boundary). Straight-sided elements: exact up to round-off.
  RefPoint cross_face(int elem, int face, const Vec3& xi) const override;

  // --- counters (thread-safe)
  std::uint64_t field_evaluations() const override { return nfield_.load(std::memory_order_relaxed); }
  std::uint64_t map_evaluations() const override { return nmap_.load(std::memory_order_relaxed); }
  void reset_counters() const {
    nfield_.store(0);
    nmap_.store(0);
  }

 private:
  struct Elem {
    int id = 0;
    NektarShape shape = NektarShape::Tetrahedron;
    std::array<int, 3> modes{};
    std::vector<double> coeffs;
    std::array<Vec3, 8> v{};  // local vertices
    Mat3 J, K;                // tetrahedra: constant
    std::array<int, 6> nb{}, nb_face{};
    Box box;
  };
  RefPoint locate_in_candidates(const Vec3& x, int hint) const;
  RefPoint nearest(const Vec3& x) const;
  Vec3 position_nocount(const Elem& e, const Vec3& xi) const;
  Mat3 jacobian_nocount(const Elem& e, const Vec3& xi) const;
  double eval_nocount(const Elem& e, const Vec3& xi, Vec3* g, Mat3* H) const;

  std::vector<Elem> elems_;
  std::unordered_map<int, int> id_to_index_;
  HpFieldParams params_;
  Box box_;
  double resolution_ = 0;
  std::string description_;
  // Uniform grid of element boxes for point location.
  std::array<int, 3> grid_n_{};
  Vec3 grid_lo_, grid_cell_;
  std::vector<int> grid_start_, grid_elems_;
  mutable std::atomic<std::uint64_t> nfield_{0}, nmap_{0};
};

/// Basis evaluation, exposed for tests and benchmarks. c: the element's
/// coefficients in Nektar++'s order; modes (P,Q,R).
namespace hp {
/// Modified_A functions psi_0..psi_{n-1} at z with first and second derivatives.
void modified_a(int n, double z, double* v, double* d, double* dd);
/// Tetrahedron expansion value through collapsed coordinates, term by term
/// as Nektar++'s backward transform does it (with its singular-vertex
/// fixes; eta clamped like Nektar++ at the collapsed edge). A reference for
/// tests: HpField uses the division-free form.
double tet_value_collapsed(const std::array<int, 3>& modes, const double* c, const Vec3& xi);
/// Division-free tetrahedron evaluation: value, and gradient and Hessian in
/// xi when g / H are not null.
double tet_evaluate(const std::array<int, 3>& modes, const double* c, const Vec3& xi, Vec3* g, Mat3* H);
/// Hexahedron (Modified_A^3) evaluation.
double hex_evaluate(const std::array<int, 3>& modes, const double* c, const Vec3& xi, Vec3* g, Mat3* H);
}  // namespace hp

}  // namespace pm
