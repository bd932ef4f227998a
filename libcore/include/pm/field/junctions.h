#pragma once
// Multi-material junctions (SPEC §6, Meyer 2008 Chapter 6): the
// inside/outside (IO) functions f̃_i = f_i - smax_{j≠i} f_j, the cell
// indicators J (sum of squared IO functions of the cell's materials), the
// projection of a motion onto a cell's tangent space, and a Gauss-Newton
// re-projection of a point onto a cell.
//
// A *cell* is a set of 2, 3 or 4 materials: the 2-cell (surface) where two
// materials meet, the 1-cell (curve) where three meet, the 0-cell (point)
// where four meet. The cell of materials {a, b, ...} is the set of points
// where f_a = f_b = ... >= f_o for every other material o.
//
// Smooth max. SPEC's reconstructed smooth max, with the sigmoid
// g(z) = 1 + z/sqrt(z² + ε) and the tie-count normalisation 1/(K 2^(m-K)),
// is implemented as smooth_max_spec() for reference, but it is NOT exact
// off ties: with one value d above the rest it returns max - O(d ε/d²), so
// at a 2-junction whose third material is near, f̃_a and f̃_b are both
// positive and J_ab has no zero at all (f̃_a = 0 needs f_a < f_b and f̃_b = 0
// needs f_b < f_a). junctions_test shows it. smooth_max() therefore uses a
// step g with compact support (C², g = 0 below -w, 2 above w, g(0) = 1) and
// normalises by the sum of the weights w_i = Π_{j≠i} g(z_i - z_j):
//   smax(Z) = Σ_i z_i w_i / Σ_i w_i.
// It is C² (the largest value always has weight >= 1) and exactly max(Z)
// whenever the largest values tie exactly and every other value lies at
// least w below them. Hence every J is exactly zero on its junction (except
// within a band of width ~w in f around the curves that bound a 2-cell,
// where the higher-order junction takes over) and positive off it.
//
// Everything is in world units (f is a signed distance: positive inside).
#include <array>
#include <cstddef>
#include <vector>

#include "pm/base/vec.h"
#include "pm/field/materials.h"

namespace pm {

/// Default width w of the smooth max's step (world units of f), about
/// sqrt(ε_max) of SPEC's ε_max = 1e-5.
constexpr double kSmoothMaxWidth = 3e-3;

/// SPEC §6 reconstructed smooth max: (1/(K 2^(m-K))) Σ_i z_i Π_{j≠i} g(z_i - z_j)
/// with g(z) = 1 + z/sqrt(z² + eps) and K the number of values tied at the
/// maximum (exact equality). For reference and tests only (see above).
/// \pre m >= 1.
double smooth_max_spec(const double* z, std::size_t m, double eps = 1e-5);

/// The C² step used by smooth_max: 0 for z <= -w, 2 for z >= w, 1 + p(z/w)
/// between, p(t) = (15t - 10t³ + 3t⁵)/8. dg (optional) receives dg/dz.
double smooth_step(double z, double w, double* dg = nullptr);

/// Smooth max of z (#m values): the weighted mean Σ z_i w_i / Σ w_i with
/// w_i = Π_{j≠i} smooth_step(z_i - z_j, width). dz (optional, #m) receives
/// ∂smax/∂z_i (they sum to 1). Costs O(m²) (O(m³) with dz).
/// \pre m >= 1, width > 0.
double smooth_max(const double* z, std::size_t m, double width = kSmoothMaxWidth, double* dz = nullptr);

/// Indicator functions f_i = -d_i (positive inside) and their gradients at a
/// point, for every material of a set.
struct IndicatorSample {
  std::vector<double> f;  ///< #M
  std::vector<Vec3> grad; ///< #M, world units
};

/// Evaluate every f_i and ∇f_i at x (uses only `m.fields`).
void sample_indicators(const MaterialSet& m, const Vec3& x, IndicatorSample& out);

/// IO function f̃_i = f_i - smax_{j≠i} f_j of material i and (optional) its
/// gradient ∇f_i - Σ_j (∂smax/∂f_j) ∇f_j. With one material: f_i.
double io_function(const IndicatorSample& s, std::size_t i, double width = kSmoothMaxWidth, Vec3* grad = nullptr);

/// A junction cell: 2, 3 or 4 distinct material indices, ascending.
struct JunctionCell {
  std::array<int, 4> m{{-1, -1, -1, -1}};  ///< material indices (into the MaterialSet), -1 unused
  int count = 0;                           ///< 2 (surface), 3 (curve) or 4 (point)
  /// Dimension of the cell: 2, 1 or 0.
  int dimension() const { return 4 - count; }
  bool contains(int material) const;
  /// True when every material of `other` belongs to this cell.
  bool contains_all(const JunctionCell& other) const;
  bool operator==(const JunctionCell& o) const { return count == o.count && m == o.m; }
  bool operator<(const JunctionCell& o) const { return count != o.count ? count < o.count : m < o.m; }
};

/// Build a cell from 2-4 material indices (sorted here).
/// \throw UsageError for fewer than 2 or more than 4 indices, or duplicates.
JunctionCell make_cell(std::vector<int> materials);

/// Cell indicator J = Σ_{i in cell} f̃_i² and (optional) ∇J = Σ 2 f̃_i ∇f̃_i.
/// Zero on the cell's junction, positive elsewhere.
double cell_indicator(const IndicatorSample& s, const JunctionCell& c, double width = kSmoothMaxWidth,
                      Vec3* grad = nullptr);

/// Project a motion v onto the tangent space of cell c from the IO normals
/// n_i = ∇f̃_i/|∇f̃_i| of its materials (io_normals[k] for c.m[k]):
///   2-cell: n = (n_a - n_b)/|n_a - n_b|, v - n (n·v);
///   1-cell: t = n_a×n_b + n_b×n_c + n_c×n_a normalised, (t·v) t;
///   0-cell: 0.
Vec3 project_to_tangent(const JunctionCell& c, const std::array<Vec3, 4>& io_normals, const Vec3& v);

struct CellProjectParams {
  int max_steps = 20;        ///< Gauss-Newton steps
  double tolerance = 1e-6;   ///< converged when every |f_a - f_b| of the cell is <= this (world units)
  double max_step = 0;       ///< longest single step, world units (0 = unlimited)
  bool check_dominance = true;  ///< also require f_o <= f_cell + tolerance for every other material o
  /// Optional value bounds of m.fields[o] (null entries allowed; see
  /// material_bounds): a material whose bound already decides the
  /// dominance check is not evaluated. The result is the same either way.
  const MaterialBounds* bounds = nullptr;
};


struct CellProjection {
  Vec3 x;                  ///< final point
  bool converged = false;  ///< residual <= tolerance within max_steps
  bool dominant = false;   ///< no other material exceeds the cell's (only with check_dominance)
  int steps = 0;           ///< Gauss-Newton steps taken
  double residual = 0;     ///< max |f_a - f_b| over the cell's consecutive pairs at x
  /// Frame at x: 2-cell: unit normal pointing from m[0] into m[1]
  /// (∇(f_b - f_a) normalised); 1-cell: unit tangent of the curve
  /// (∇(f_a - f_b) × ∇(f_b - f_c) normalised); 0-cell: zero.
  Vec3 frame;
  double value = 0;        ///< f of the cell's first material at x
  std::size_t evaluations = 0;  ///< field evaluations used
  std::size_t bounded = 0;      ///< dominance checks decided by the bounds, without an evaluation
};

/// Re-project x onto the junction of cell c by Gauss-Newton on the system
/// r_k = f_{m[k]} - f_{m[k+1]} = 0 (k < count-1; the same zero set as the
/// cell's IO functions wherever the smooth max is exact, with full-rank
/// rows): x <- x - Rᵀ (R Rᵀ)⁻¹ r, R the rows ∇r_k (minimum-norm step;
/// Newton for a 0-cell). Converges quadratically near a transversal
/// junction. Stops (converged = false) on a singular system, a non-finite
/// value, or after max_steps.
CellProjection project_to_cell(const MaterialSet& m, const JunctionCell& c, const Vec3& x,
                               const CellProjectParams& p = {});

}  // namespace pm
