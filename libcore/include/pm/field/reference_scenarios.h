#pragma once
// The built-in scenarios of Chapter 4 (SPEC §4, Meyer 2008 Table 4.1;
// issue #18), made in code, no files:
//  * TeardropField: a sphere in reference space, F*(u) = |u - c|^2, u in
//    [0,1]^3, mapped to world space by a trivariate quadratic B-spline
//    (uniform open knots, n spans per axis, so n^3 curvilinear hexahedral
//    elements) whose control net tapers towards +z, which turns the sphere
//    into a teardrop. Each element is one knot span; its reference
//    coordinates xi in [-1,1]^3 are the span's u affinely. The map is C1
//    across element faces, so a face crossing is exact in u.
//  * hex_power_field: one hexahedron with an order-k polynomial
//    u = x^k + y^k + z^k in Nektar++'s Modified_A basis (k + 1 modes),
//    as an HpField.
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "pm/field/hp_field.h"
#include "pm/field/reference_field.h"

namespace pm {

struct TeardropParams {
  int spans = 2;            ///< knot spans (elements) per axis, >= 1
  Vec3 centre{0.5, 0.5, 0.5};  ///< sphere centre in u
  double radius = 0.4;      ///< sphere radius in u (the isovalue is radius^2)
  double size = 2;          ///< world extent of the control net at its base, world units
  double taper = 0.85;      ///< control net width at the top = (1 - taper) x the base width, in [0, 1)
  double height = 2;        ///< world height, world units
};

class TeardropField : public ReferenceField {
 public:
  /// \throw UsageError when spans < 1, radius <= 0, taper outside [0, 1), size or height <= 0.
  explicit TeardropField(TeardropParams params = {});

  /// Isovalue of the sphere: radius^2.
  double iso() const { return p_.radius * p_.radius; }
  /// Global reference coordinates u of (elem, xi).
  Vec3 global(int elem, const Vec3& xi) const;
  /// T(u): the B-spline map, without counting.
  Vec3 map(const Vec3& u) const;
  const TeardropParams& params() const { return p_; }

  int num_elements() const override { return n_ * n_ * n_; }
  NektarShape shape(int) const override { return NektarShape::Hexahedron; }
  int element_id(int elem) const override { return elem; }
  std::array<int, 3> modes(int) const override { return {3, 3, 3}; }
  std::vector<Vec3> element_vertices(int elem) const override;
  double ref_value(int elem, const Vec3& xi) const override;
  HpSample sample(int elem, const Vec3& xi) const override;
  int exit_face(int elem, const Vec3& xi, double tol = 0) const override;
  Vec3 clamp_to_element(int elem, const Vec3& xi) const override;
  bool inverse_map(int elem, const Vec3& x, Vec3& xi) const override;
  RefPoint locate(const Vec3& x, int hint = -1) const override;
  RefPoint cross_face(int elem, int face, const Vec3& xi) const override;
  Box domain() const override { return box_; }
  double resolution() const override { return resolution_; }
  std::string describe() const override;
  std::uint64_t field_evaluations() const override { return nfield_.load(std::memory_order_relaxed); }
  std::uint64_t map_evaluations() const override { return nmap_.load(std::memory_order_relaxed); }

 private:
  // T, dT/du and d2T^a/du2 in the knot span (i, j, k) at u (extrapolated outside it).
  Vec3 eval_map(const std::array<int, 3>& span, const Vec3& u, Mat3* J, Mat3* d2T) const;
  std::array<int, 3> span_of(int elem) const { return {elem % n_, (elem / n_) % n_, elem / (n_ * n_)}; }
  int elem_of(const std::array<int, 3>& s) const { return s[0] + n_ * (s[1] + n_ * s[2]); }

  TeardropParams p_;
  int n_ = 2;
  std::vector<double> knots_;  // n + 5 knots
  std::vector<Vec3> ctrl_;     // (n + 2)^3 control points, i fastest
  Box box_;
  double resolution_ = 0;
  mutable std::atomic<std::uint64_t> nfield_{0}, nmap_{0};
};

/// A single hexahedron [lo, hi] (world units) holding u = x^k + y^k + z^k
/// (x, y, z world coordinates) exactly in Modified_A with k + 1 modes per
/// direction (1 <= k <= 12). `mesh` and `field` must outlive the HpField.
struct HexPowerScenario {
  NektarMesh mesh;
  NektarField field;
};
HexPowerScenario hex_power_field(int k, const Vec3& lo, const Vec3& hi);

}  // namespace pm
