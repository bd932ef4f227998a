// HpConstraint: particles in the reference spaces of a high-order field,
// and distribute_hp_particles, its configuration of the one particle engine
// (seeds from per-element reference lattices, population control, result).
#include "pm/sample/hp_constraint.h"

#include <tbb/blocked_range.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/parallel.h"
#include "pm/sample/surface_constraint.h"

#include "engine_impl.h"

namespace pm {

namespace {
constexpr double kInsideTol = 1e-12;   // reference-space slack of "inside the element"
constexpr int kMaxCrossings = 16;      // face crossings per settle at most
constexpr double kFlatGradient2 = 1e-300;
constexpr double kWallGradient2 = 1e-6;  // |g within a boundary face|² / |g|² below this: the surface is parallel to it
constexpr int kMaxSeedPoints = 64;     // seeding lattice points per element edge at most
constexpr double kSeedStep = 2.0;      // default seeding lattice step, × s
constexpr double kNewtonStall = 0.25;  // |r| above this × the last |r| after a face crossing: Newton stalled at a kink
constexpr int kMaxLevels = 8;          // coarse-to-fine levels at most
constexpr double kCoarseResolutions = 4;  // default coarsest spacing: 4 field resolutions
}  // namespace

HpConstraint::HpConstraint(const ReferenceField& field, double iso, bool curvature, double eps)
    : f_(field), iso_(iso), curvature_(curvature), eps_(eps) {}

bool HpConstraint::settle(int& elem, Vec3& xi, int* wall) const {
  if (wall) *wall = -1;
  for (int k = 0; k <= kMaxCrossings; ++k) {
    if (!is_finite(xi)) return false;
    const int face = f_.exit_face(elem, xi, kInsideTol);
    if (face < 0) return true;
    const RefPoint r = f_.cross_face(elem, face, xi);
    if (r.elem < 0) {  // a boundary face: stop on the mesh boundary
      xi = f_.clamp_to_element(elem, xi);
      if (wall) *wall = face;
      return true;
    }
    elem = r.elem;
    xi = r.xi;
  }
  return false;
}

namespace {
// Outward normal of local face `face` in reference coordinates (see pm/field/hp_field.h).
Vec3 reference_face_normal(NektarShape shape, int face) {
  static const Vec3 tet[4] = {{0, 0, -1}, {0, -1, 0}, {1, 1, 1}, {-1, 0, 0}};
  static const Vec3 hex[6] = {{0, 0, -1}, {0, -1, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, 0, 1}};
  return shape == NektarShape::Tetrahedron ? tet[face] : hex[face];
}
}  // namespace

bool HpConstraint::accept(int elem, const Vec3& xi, const HpSample& s, Point& out, Probe& pr) const {
  const double gg = norm2(s.grad);
  if (!(gg > kFlatGradient2)) return pr.fail(ProjectFailure::flat);
  out.x = s.x;
  out.n = s.grad / std::sqrt(gg);
  out.s.element = std::int32_t(elem);
  out.s.xi = xi;
  out.s.K = s.K;
  out.s.residual = s.f - iso_;
  out.s.curvedness = curvature_ ? curvedness_of(s.grad, s.hess) : 0.0;
  return true;
}

bool HpConstraint::project(int elem, Vec3 xi, int steps, Point& out, Probe& pr) const {
  // wall: a face of elem that xi lies on and that Newton must not leave by
  // (a boundary face it was clamped onto, or an element face where the
  // field's kink stalled Newton), -1 when none.
  int wall = -1;
  if (!settle(elem, xi, &wall))
    return pr.fail(is_finite(xi) ? ProjectFailure::left_domain : ProjectFailure::non_finite);
  Vec3 xi_try;
  double r_prev = 0;
  int e_prev = -1;
  bool crossed = false;
  for (int k = 0;; ++k) {
    ++pr.evaluations;
    const HpSample s = f_.sample(elem, xi);
    const double r = s.f - iso_;
    if (!std::isfinite(r) || !is_finite(s.grad)) return pr.fail(ProjectFailure::non_finite);
    const double gg = norm2(s.grad);
    if (std::fabs(r) <= eps_) return accept(elem, xi, s, out, pr);
    if (k >= steps) return pr.fail(ProjectFailure::no_convergence);
    const bool stalled = e_prev >= 0 && std::fabs(r) > kNewtonStall * std::fabs(r_prev);
    if (stalled && crossed) {
      // The step crossed an element face and Newton stalled (the field is
      // only C0 there): go back to where the step crossed the face and go
      // on within the face's plane.
      elem = e_prev;
      wall = f_.exit_face(elem, xi_try, 0);
      xi = f_.clamp_to_element(elem, xi_try);
      crossed = false;
      e_prev = -1;
      continue;
    }
    if (!(gg > kFlatGradient2)) return pr.fail(ProjectFailure::flat);
    r_prev = r;
    e_prev = elem;
    // Minimum-norm world correction -(r/|g|²) g, pulled back with K; on a
    // wall face, when that correction points out through it, the
    // minimum-norm correction within the face's plane instead.
    Vec3 dx = s.grad * (-r / gg);
    bool constrained = false;
    if (wall >= 0) {
      const Vec3 m = normalized(transpose(s.K) * reference_face_normal(f_.shape(elem), wall));
      if (dot(dx, m) > 0) {
        const Vec3 gt = s.grad - m * dot(s.grad, m);
        const double gt2 = norm2(gt);
        if (gt2 > kWallGradient2 * gg) {
          dx = gt * (-r / gt2);
          constrained = true;
        }
      }
    }
    xi += s.K * dx;
    xi_try = xi;
    if (!is_finite(xi)) return pr.fail(ProjectFailure::non_finite);
    int w = -1;
    if (!settle(elem, xi, &w)) return pr.fail(ProjectFailure::left_domain);
    crossed = elem != e_prev;
    if (w >= 0)
      wall = w;
    else if (!(constrained && !crossed))
      wall = -1;
  }
}

bool HpConstraint::place_reference(int elem, const Vec3& xi, int steps, Point& out, Probe& pr) const {
  if (elem < 0 || elem >= f_.num_elements()) return pr.fail(ProjectFailure::left_domain);
  return project(elem, xi, steps, out, pr);
}

bool HpConstraint::place(const Vec3& x, const Point& like, int steps, double, Point& out, Probe& pr) const {
  if (!is_finite(x)) return pr.fail(ProjectFailure::non_finite);
  const int hint = like.s.element;
  RefPoint r = f_.locate(x, hint);
  if (r.elem < 0) {  // outside the mesh: from like's element, clamped onto the boundary
    if (hint < 0 || hint >= f_.num_elements() || !f_.inverse_map(hint, x, r.xi))
      return pr.fail(ProjectFailure::left_domain);
    r.elem = hint;
  }
  return project(r.elem, r.xi, steps, out, pr);
}

bool HpConstraint::move(const Point& from, const Vec3& step, int steps, double, Point& out, Probe& pr) const {
  return project(from.s.element, from.s.xi + from.s.K * step, steps, out, pr);
}

template class ParticleEngine<HpConstraint>;

// ---------------------------------------------------------------------------

namespace {

using Engine = ParticleEngine<HpConstraint>;
using HpPoint = HpConstraint::Point;

struct RefSeed {
  int elem;
  Vec3 xi;
};

// Crossings of u = iso along the edges of an equispaced lattice of n points
// per edge in every element's reference space (tetrahedra: i + j + k <= n - 1),
// linear interpolation in xi. lo/hi: the lattice values' range.
std::vector<RefSeed> reference_lattice_seeds(const ReferenceField& f, double iso, const std::vector<int>& points, double& lo,
                                             double& hi) {
  const int ne = f.num_elements();
  std::vector<std::vector<RefSeed>> per(static_cast<std::size_t>(ne));
  std::vector<double> elo(static_cast<std::size_t>(ne)), ehi(static_cast<std::size_t>(ne));
  pm::parallel_for(tbb::blocked_range<int>(0, ne), [&](const tbb::blocked_range<int>& range) {
    for (int e = range.begin(); e != range.end(); ++e) {
      const int n = points[static_cast<std::size_t>(e)];
      const bool tet = f.shape(e) == NektarShape::Tetrahedron;
      auto valid = [&](int i, int j, int k) { return i < n && j < n && k < n && (!tet || i + j + k <= n - 1); };
      auto xi_of = [&](int i, int j, int k) {
        const double h = 2.0 / (n - 1);
        return Vec3{-1 + h * i, -1 + h * j, -1 + h * k};
      };
      std::vector<double> v(static_cast<std::size_t>(n * n * n), std::numeric_limits<double>::quiet_NaN());
      auto at = [&](int i, int j, int k) -> double& { return v[static_cast<std::size_t>(i + n * (j + n * k))]; };
      double mn = std::numeric_limits<double>::infinity(), mx = -mn;
      for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i)
            if (valid(i, j, k)) {
              const double u = f.ref_value(e, xi_of(i, j, k)) - iso;
              at(i, j, k) = u;
              mn = std::min(mn, u);
              mx = std::max(mx, u);
            }
      elo[static_cast<std::size_t>(e)] = mn + iso;
      ehi[static_cast<std::size_t>(e)] = mx + iso;
      auto& out = per[static_cast<std::size_t>(e)];
      for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            if (!valid(i, j, k)) continue;
            const double a = at(i, j, k);
            const int d[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
            for (const auto& dd : d) {
              const int ii = i + dd[0], jj = j + dd[1], kk = k + dd[2];
              if (!valid(ii, jj, kk)) continue;
              const double b = at(ii, jj, kk);
              if (!std::isfinite(a) || !std::isfinite(b) || (a < 0) == (b < 0) || a == b) continue;
              const double t = a / (a - b);
              out.push_back({e, xi_of(i, j, k) + (xi_of(ii, jj, kk) - xi_of(i, j, k)) * t});
            }
          }
    }
  });
  lo = std::numeric_limits<double>::infinity();
  hi = -lo;
  std::vector<RefSeed> all;
  for (int e = 0; e < ne; ++e) {
    lo = std::min(lo, elo[static_cast<std::size_t>(e)]);
    hi = std::max(hi, ehi[static_cast<std::size_t>(e)]);
    all.insert(all.end(), per[static_cast<std::size_t>(e)].begin(), per[static_cast<std::size_t>(e)].end());
  }
  return all;
}

double element_diameter(const ReferenceField& f, int e) {
  const std::vector<Vec3> v = f.element_vertices(e);
  double d = 0;
  for (std::size_t a = 0; a < v.size(); ++a)
    for (std::size_t b = a + 1; b < v.size(); ++b) d = std::max(d, norm(v[a] - v[b]));
  return d;
}

}  // namespace

HpParticleResult distribute_hp_particles(const ReferenceField& field, const HpParticleParams& p) {
  const double diag = norm(field.domain().size());
  if (!(p.spacing > 0) || !std::isfinite(p.spacing))
    throw UsageError("spacing must be > 0 world units, got " + engine_fmt(p.spacing));
  if (p.spacing > diag)
    throw UsageError("spacing " + engine_fmt(p.spacing) + " is larger than the mesh's diagonal " + engine_fmt(diag) +
                     " (world units); expected a spacing well below the size of the surface");
  if (!(p.density >= 0) || !std::isfinite(p.density))
    throw UsageError("density must be >= 0 particles per radian, got " + engine_fmt(p.density));
  if (!(p.alpha_cap >= 1)) throw UsageError("alpha cap must be >= 1, got " + engine_fmt(p.alpha_cap));
  if (!(p.eps > 0)) throw UsageError("Newton tolerance must be > 0, got " + engine_fmt(p.eps));
  if (!(p.tolerance > 0)) throw UsageError("tolerance must be > 0, got " + engine_fmt(p.tolerance));
  if (p.max_iters < 1) throw UsageError("max iterations must be >= 1, got " + std::to_string(p.max_iters));
  if (p.seed_points < 0 || p.seed_points == 1)
    throw UsageError("seed lattice points per element edge must be 0 (automatic) or >= 2, got " +
                     std::to_string(p.seed_points));
  if (!(p.seed_thinning >= 0 && p.seed_thinning < 2))
    throw UsageError("seed thinning must be in [0, 2) spacings, got " + engine_fmt(p.seed_thinning));
  if (p.reproject_steps < 1)
    throw UsageError("reprojection steps must be >= 1, got " + std::to_string(p.reproject_steps));

  Stopwatch sw;
  HpParticleResult res;
  const std::uint64_t f0 = field.field_evaluations(), m0 = field.map_evaluations();

  int levels = 0;
  if (p.coarse_to_fine) {
    const double start = p.coarse_start > 0 ? p.coarse_start : kCoarseResolutions * field.resolution();
    while (levels < kMaxLevels && p.spacing * std::ldexp(1.0, levels + 1) <= start * (1 + 1e-9)) ++levels;
  }
  const double seed_spacing = p.spacing * std::ldexp(1.0, levels);
  // Seeds: crossings of a reference lattice per element.
  std::vector<int> points(static_cast<std::size_t>(field.num_elements()));
  for (int e = 0; e < field.num_elements(); ++e) {
    const auto md = field.modes(e);
    int n = p.seed_points;
    if (n == 0) {
      const double want = std::ceil(element_diameter(field, e) / (kSeedStep * seed_spacing)) + 1;
      n = std::max(*std::max_element(md.begin(), md.end()) + 1, int(std::min<double>(want, kMaxSeedPoints)));
    }
    points[static_cast<std::size_t>(e)] = n;
  }
  double lo = 0, hi = 0;
  const std::vector<RefSeed> seeds = reference_lattice_seeds(field, p.iso, points, lo, hi);
  res.seed_evaluations = field.field_evaluations() - f0;
  if (seeds.empty())
    throw InputError("no isosurface F = " + engine_fmt(p.iso) + " in " + field.describe() +
                     ": the seeding lattice's values lie in [" + engine_fmt(lo) + ", " + engine_fmt(hi) +
                     "]; expected an isovalue strictly inside the field's range");
  res.seeds = seeds.size();

  const HpConstraint c(field, p.iso, p.density > 0, p.eps);
  EngineParams ep;
  copy_relax_params(p, ep);
  ep.population_control = true;
  ep.sizing_mode = false;
  ep.spacing = p.spacing;
  ep.density = p.density;
  ep.alpha_cap = p.alpha_cap;
  Engine eng(c, ep);

  std::vector<HpPoint> placed(seeds.size());
  std::vector<char> ok(seeds.size(), 0);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, seeds.size(), 64), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k) {
      Probe pr;
      ok[k] = c.place_reference(seeds[k].elem, seeds[k].xi, engine_constants::kPlaceSteps, placed[k], pr);
    }
  });
  for (std::size_t k = 0; k < seeds.size(); ++k)
    if (ok[k]) eng.add(placed[k]);
    else ++res.dropped_init;
  if (eng.particles().empty())
    throw InputError("no seed of the " + std::to_string(seeds.size()) + " lattice crossings reached u = " +
                     engine_fmt(p.iso) + " in " + field.describe() + " within " +
                     std::to_string(engine_constants::kPlaceSteps) + " Newton steps");
  eng.set_scale(std::ldexp(1.0, levels));
  eng.refresh_spacings();
  eng.set_anchors_from_particles();
  if (levels == 0) eng.guard_anchors();
  if (p.seed_thinning > 0) res.thinned = eng.thin_particles(p.seed_thinning);

  for (int level = levels; level >= 0; --level) {
    if (level == 0 && levels > 0) {  // from here on every anchor keeps a particle near it
      eng.guard_anchors();
      eng.refill_holes();
    }
    const std::string label =
        levels > 0 ? "level " + std::to_string(levels - level + 1) + "/" + std::to_string(levels + 1) : "relax";
    const Engine::LevelResult lr = eng.relax(label, false);
    res.iterations += lr.iterations;
    res.converged = lr.converged;
    res.splits += lr.splits;
    res.deletions += lr.deletions;
    if (level > 0) eng.split_all();
  }
  res.levels = levels + 1;

  const double energy = eng.measure();
  // Output in a deterministic order: element, then position.
  eng.stable_order([](const Engine::Particle& q) { return q.p.s.element; });
  const auto& parts = eng.particles();
  const std::size_t n = parts.size();
  res.positions.resize(n);
  res.normals.resize(n);
  res.element.resize(n);
  res.xi.resize(n);
  res.residual.resize(n);
  res.energy.resize(n);
  res.spacing.resize(n);
  std::uint64_t nb = 0;
  double ideal = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& q = parts[i];
    res.positions[i] = q.p.x;
    res.normals[i] = q.p.n;
    res.element[i] = field.element_id(q.p.s.element);
    res.xi[i] = q.p.s.xi;
    res.residual[i] = std::fabs(q.p.s.residual);
    res.energy[i] = q.energy;
    res.spacing[i] = q.spacing;
    nb += std::uint64_t(q.neighbours);
    ideal += eng.ideal_energy(q);
  }
  res.energy_final = energy;
  res.energy_ideal = ideal;
  res.mean_neighbours = n ? double(nb) / double(n) : 0.0;
  res.engine = eng.stats();
  res.field_evaluations = field.field_evaluations() - f0;
  res.map_evaluations = field.map_evaluations() - m0;
  res.seconds = sw.seconds();
  return res;
}

}  // namespace pm
