#pragma once
// Constraint of the particle engine (pm/sample/engine.h): the junction
// cells of a multi-material set (SPEC §6, Meyer 2008 Chapter 6), of any
// order: 2-cells (surfaces between two materials), 1-cells (curves where
// three meet), 0-cells (points where four meet). A particle carries its cell
// and the residual of its projection; its SamplePoint normal is the cell's
// frame (surface normal from the first material into the second, or curve
// tangent). Projection: pm::project_to_cell (Gauss-Newton), rejected when it
// leaves the domain or another material dominates. Particles see the
// particles of their own cell and the fixed particles of every cell that
// bounds it (whose materials include all of its own): lower levels are
// sampled first, fixed, and repel the higher ones.
#include <cstdint>
#include <map>
#include <vector>

#include "pm/field/junctions.h"
#include "pm/field/materials.h"
#include "pm/sample/engine.h"

namespace pm {

class JunctionConstraint {
 public:
  struct State {
    std::int32_t cell = 0;  ///< index into cells()
    double residual = 0;    ///< max |f_a - f_b| over the cell at the point, world units
  };
  using Point = SamplePoint<State>;

  /// tolerance: largest |f_a - f_b| on a cell (world units, > 0).
  JunctionConstraint(const MaterialSet& m, const Box& domain, double tolerance);

  /// Index of a cell (added when new); call finish_cells() before sampling.
  std::int32_t cell_index(const JunctionCell& c);
  /// Precompute which cells bound which (visibility).
  void finish_cells();
  const std::vector<JunctionCell>& cells() const { return cells_; }
  const JunctionCell& cell(const Point& p) const { return cells_[std::size_t(p.s.cell)]; }
  /// A point of cell `c` (no position yet) to use as `like` for place().
  Point of_cell(std::int32_t c) const {
    Point p;
    p.s.cell = c;
    return p;
  }

  bool place(const Vec3& x, const Point& like, int steps, double max_step, Point& out, Probe& pr) const;
  bool move(const Point& from, const Vec3& step, int steps, double max_step, Point& out, Probe& pr) const {
    return place(from.x + step, from, steps, max_step, out, pr);
  }
  /// 2-cell: v - n (n·v); 1-cell: t (t·v); 0-cell: 0.
  Vec3 tangent(const Point& p, const Vec3& v) const;
  int dimension(const Point& p) const { return cell(p).dimension(); }
  /// 2 on curves, 6 on surfaces (SPEC §6).
  double ideal_neighbours(const Point& p) const { return cell(p).count == 3 ? 2 : 6; }
  double split_below(const Point& p) const { return cell(p).count == 3 ? 0.25 : 0.35; }
  double delete_above(const Point& p) const { return cell(p).count == 3 ? 2.5 : 1.75; }
  /// Curves: ±dist along the tangent (u < 1/2: forward); surfaces: dist in
  /// the tangent plane at angle 2πu.
  Vec3 split_offset(const Point& p, double u, double dist) const;
  int children(const Point& p, double theta, double dist, Vec3* out) const;
  bool sees(const Point& i, const Point& o, bool o_fixed) const { return sees_key(i, o.s.cell, o_fixed); }
  /// Normal weighting between particles of one surface cell only.
  bool weighted(const Point& p) const { return cell(p).count == 2; }
  bool same_cell(const Point& a, const Point& b) const { return a.s.cell == b.s.cell; }
  /// The pair rules from the other particle's cell (the engine caches it
  /// beside the particle's pair data: a gather reads no particle).
  static constexpr bool kKeyedPairs = true;
  std::int32_t pair_key(const Point& o) const { return o.s.cell; }
  bool sees_key(const Point& i, std::int32_t o_cell, bool o_fixed) const {
    return o_cell == i.s.cell || (o_fixed && vis_[std::size_t(i.s.cell) * cells_.size() + std::size_t(o_cell)]);
  }
  bool weighted_key(const Point& i, std::int32_t o_cell) const { return weighted(i) && o_cell == i.s.cell; }
  double curvedness(const Point&) const { return 0; }

 private:
  const MaterialSet& m_;
  Box domain_;
  double tol_;
  // Value bounds of the material fields: most dominance checks are decided
  // without evaluating the materials far from the cell (same result).
  MaterialBounds bounds_;
  std::vector<JunctionCell> cells_;
  std::map<JunctionCell, std::int32_t> ids_;
  std::vector<char> vis_;  // vis_[a * nc + b]: cell b bounds cell a (b ⊇ a, b != a)
};

}  // namespace pm
