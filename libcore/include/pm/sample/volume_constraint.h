#pragma once
// Constraint of the particle engine (pm/sample/engine.h): the inside of an
// implicit, F < iso (sphere packing in volumes, Meyer 2008 Chapter 7).
// Particles move freely (no tangent projection, no normal weighting) but
// never leave the region; the ideal packing has 12 neighbours (SPEC §3).
#include "pm/field/field.h"
#include "pm/sample/engine.h"

namespace pm {

class VolumeConstraint {
 public:
  struct State {};  ///< a world point needs nothing else
  using Point = SamplePoint<State>;

  /// Particles stay where F(x) < iso and inside the field's domain.
  VolumeConstraint(const ScalarField& field, double iso);

  /// x itself when inside; else Newton towards F = iso - inset (inset = 1e-3
  /// field resolutions × |∇F|), then x when that is inside.
  bool place(const Vec3& x, const Point& like, int steps, double max_step, Point& out, Probe& pr) const;
  /// from.x + step when inside (fails with left_domain otherwise).
  bool move(const Point& from, const Vec3& step, int steps, double max_step, Point& out, Probe& pr) const;
  Vec3 tangent(const Point&, const Vec3& v) const { return v; }
  int dimension(const Point&) const { return 3; }
  double ideal_neighbours(const Point&) const { return 12; }
  double split_below(const Point&) const { return 0.35; }
  double delete_above(const Point&) const { return 1.75; }
  /// `dist` along a direction on the unit sphere picked by u (a spiral).
  Vec3 split_offset(const Point&, double u, double dist) const;
  /// The 8 corners ±dist of a cube turned by theta about z.
  int children(const Point&, double theta, double dist, Vec3* out) const;
  bool sees(const Point&, const Point&, bool) const { return true; }
  bool weighted(const Point&) const { return false; }
  bool same_cell(const Point&, const Point&) const { return true; }
  static constexpr bool kPairFree = true;  ///< see SurfaceRules
  double curvedness(const Point&) const { return 0; }

  bool inside(const Vec3& x, Probe& pr) const;

 private:
  const ScalarField& field_;
  double iso_;
  Box domain_;
};

}  // namespace pm
