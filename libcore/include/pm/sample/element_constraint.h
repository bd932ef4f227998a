#pragma once
// Constraint of the particle engine (pm/sample/engine.h) whose particle
// state is not a world point: an element id and reference coordinates u in
// [0, 1]³ of a mapped element x = φ_e(u) (high-order finite elements, Meyer
// 2008 Chapter 4). The set is G(u) = 0 for an implicit G given in reference
// space; the world position, the Jacobian J = ∂φ/∂u and the world normal
// J⁻ᵀ ∇G / |J⁻ᵀ ∇G| are computed from the state. A world move v is projected
// onto the world tangent plane, pulled back (du = J⁻¹ v, which lies in the
// reference tangent plane) and re-projected by Newton on G in reference
// space. Pair energies stay in world units, so the packing is uniform on the
// mapped surface however the element distorts it.
#include <array>
#include <cstdint>
#include <vector>

#include "pm/field/field.h"
#include "pm/sample/engine.h"

namespace pm {

/// Mapped elements: φ_e maps the unit cube [0, 1]³ of element e to world space.
class ElementMap {
 public:
  virtual ~ElementMap() = default;
  virtual std::size_t size() const = 0;
  /// World point φ_e(u) and (optional) Jacobian ∂φ/∂u (columns ∂φ/∂u_k).
  virtual Vec3 world(std::size_t e, const Vec3& u, Mat3* jacobian) const = 0;
};

/// Trilinear hexahedra: element e has 8 corners, corner (i, j, k) ∈ {0, 1}³
/// at index i + 2j + 4k, world units.
class TrilinearElements : public ElementMap {
 public:
  explicit TrilinearElements(std::vector<std::array<Vec3, 8>> corners) : corners_(std::move(corners)) {}
  std::size_t size() const override { return corners_.size(); }
  Vec3 world(std::size_t e, const Vec3& u, Mat3* jacobian) const override;

 private:
  std::vector<std::array<Vec3, 8>> corners_;
};

class ElementConstraint : public SurfaceRules {
 public:
  struct State {
    std::int32_t element = 0;
    Vec3 u{0.5, 0.5, 0.5};  ///< reference coordinates in [0, 1]³
    Mat3 jacobian;          ///< ∂φ/∂u at u
    Vec3 ref_grad;          ///< ∇G at u (reference units)
  };
  using Point = SamplePoint<State>;

  /// reference: G over reference space (its domain should hold [0, 1]³);
  /// particles live on G = 0 inside one element each.
  ElementConstraint(const ElementMap& map, const ScalarField& reference);

  /// The state of element `e` at reference point u projected onto G = 0.
  bool place_reference(std::size_t e, const Vec3& u, int steps, Point& out, Probe& pr) const;
  /// World x: invert φ of like's element by Newton from like's u, then project.
  bool place(const Vec3& x, const Point& like, int steps, double max_step, Point& out, Probe& pr) const;
  bool move(const Point& from, const Vec3& step, int steps, double max_step, Point& out, Probe& pr) const;
  double curvedness(const Point&) const { return 0; }

 private:
  // Newton on G from u within the element; fills out from the result.
  bool project(std::size_t e, Vec3 u, int steps, Point& out, Probe& pr) const;
  const ElementMap& map_;
  const ScalarField& g_;
};

}  // namespace pm
