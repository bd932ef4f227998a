// distribute_particles: the implicit-surface configuration of the one
// particle engine (pm/sample/engine.h with pm/sample/surface_constraint.h):
// initial points (seeds, lattice crossings or random points), anchors,
// coarse-to-fine levels or a fixed count, and the result.
#include "pm/sample/particles.h"

#include <tbb/blocked_range.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/parallel.h"
#include "pm/sample/engine.h"
#include "pm/sample/surface_constraint.h"

namespace pm {
namespace {

using Engine = ParticleEngine<SurfaceConstraint>;
using Point = SurfaceConstraint::Point;
using engine_constants::kPi;
using engine_constants::kPlaceSteps;

constexpr int kMaxLevels = 8;              // coarse-to-fine levels at most
constexpr double kCoarseVoxels = 4;        // default coarsest spacing: 4 field resolutions
constexpr double kLatticePerSpacing = 1.15;  // lattice step / spacing (a plane crosses 1.5 edges per step²,
                                             // the hexagonal packing has 1.155 particles per s²)
constexpr double kLatticeMaxNodes = 256;   // lattice steps along the longest axis at most (~17M nodes)
constexpr double kCountChildOffset = 0.3;  // fixed count: extra particles this many spacings from a parent
constexpr int kCountRounds = 64;           // fixed count: doubling rounds at most

// Linear-interpolated crossings of F = iso on the edges of a lattice with the
// given step over the domain (deterministic order).
std::vector<Vec3> lattice_crossings(const ScalarField& field, double iso, double step, std::uint64_t& evals) {
  const Box domain = field.domain();
  const Vec3 lo = domain.lo, sz = domain.size();
  const double longest = std::max({sz.x, sz.y, sz.z});
  step = std::max(step, longest / kLatticeMaxNodes);
  const std::size_t nx = std::size_t(std::floor(sz.x / step)) + 1, ny = std::size_t(std::floor(sz.y / step)) + 1,
                    nz = std::size_t(std::floor(sz.z / step)) + 1;
  auto node = [&](std::size_t i, std::size_t j, std::size_t k) {
    return lo + Vec3{double(i) * step, double(j) * step, double(k) * step};
  };
  std::vector<float> f(nx * ny * nz);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, nz), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k)
      for (std::size_t j = 0; j < ny; ++j)
        for (std::size_t i = 0; i < nx; ++i) {
          const double v = field.value(node(i, j, k)) - iso;
          f[i + nx * (j + ny * k)] = std::isfinite(v) ? float(v) : 0.0f;
        }
  });
  evals += f.size();
  std::vector<Vec3> xs;
  for (std::size_t k = 0; k < nz; ++k)
    for (std::size_t j = 0; j < ny; ++j)
      for (std::size_t i = 0; i < nx; ++i) {
        const float a = f[i + nx * (j + ny * k)];
        const Vec3 x = node(i, j, k);
        auto edge = [&](bool inside, std::size_t ii, std::size_t jj, std::size_t kk, const Vec3& dir) {
          if (!inside) return;
          const float b = f[ii + nx * (jj + ny * kk)];
          if ((a < 0) == (b < 0) || a == b) return;
          xs.push_back(x + dir * (step * double(a / (a - b))));
        };
        edge(i + 1 < nx, i + 1, j, k, {1, 0, 0});
        edge(j + 1 < ny, i, j + 1, k, {0, 1, 0});
        edge(k + 1 < nz, i, j, k + 1, {0, 0, 1});
      }
  return xs;
}

class SurfaceRun {
 public:
  SurfaceRun(const ScalarField& field, const SizingField* sizing, const ParticleParams& p)
      : field_(field), sizing_(sizing), p_(p), c_(field, p.iso, sizing == nullptr && p.density > 0),
        e_(c_, engine_params(sizing, p)) {}

  ParticleResult run(const std::vector<Vec3>& seeds);

 private:
  static EngineParams engine_params(const SizingField* sizing, const ParticleParams& p) {
    EngineParams e;
    copy_relax_params(p, e);
    e.population_control = p.population_control;
    e.sizing_mode = sizing != nullptr;
    e.sizing = sizing;
    e.spacing = p.spacing;
    e.density = p.density;
    e.alpha_cap = p.alpha_cap;
    e.sub_bins = engine_constants::kSubBins;
    if (p.quads) set_quad_types(e);
    if (!p.quads) e.first_population_interval = engine_constants::kFirstPopulationInterval;
    return e;
  }
  int coarse_levels(double base) const {
    if (!p_.coarse_to_fine || p_.count != 0) return 0;
    const double start = p_.coarse_start > 0 ? p_.coarse_start : kCoarseVoxels * field_.resolution();
    int levels = 0;
    while (levels < kMaxLevels && base * std::ldexp(1.0, levels + 1) <= start * (1 + 1e-9)) ++levels;
    return levels;
  }
  std::vector<Engine::Candidate> candidates(const std::vector<Vec3>& xs) const {
    std::vector<Engine::Candidate> c(xs.size());
    for (std::size_t k = 0; k < xs.size(); ++k) c[k].x = xs[k];
    return c;
  }
  void initialise(const std::vector<Vec3>& seeds, double lattice_step, ParticleResult& res);
  // Quad packing: each initial point's type from the counter RNG (half each).
  std::uint8_t init_type(std::size_t k) const {
    return p_.quads ? std::uint8_t(counter_uniform(p_.seed, k, 0, kStreamType) < 0.5) : 0;
  }
  void fill_to_count();

  const ScalarField& field_;
  const SizingField* sizing_;
  ParticleParams p_;
  SurfaceConstraint c_;
  Engine e_;
};

void SurfaceRun::initialise(const std::vector<Vec3>& seeds, double lattice_step, ParticleResult& res) {
  std::vector<Vec3> xs;
  std::uint64_t evals = 0;
  if (seeds.empty() && lattice_step > 0) xs = lattice_crossings(field_, p_.iso, lattice_step, evals);
  e_.stats().field_evaluations += evals;
  if (!xs.empty()) {
    // lattice crossings: placed below like random points
  } else if (!seeds.empty()) {
    for (std::size_t k = 0; k < seeds.size(); ++k)
      if (!is_finite(seeds[k]))
        throw InputError("seed point " + std::to_string(k) + " is not finite: " + engine_fmt(seeds[k]) +
                         "; expected finite world coordinates");
    xs = seeds;
  } else {
    const Box dom = field_.domain();
    const Vec3 lo = dom.lo, sz = dom.size();
    xs.resize(p_.init_count);
    for (std::size_t k = 0; k < xs.size(); ++k)
      xs[k] = lo + Vec3{sz.x * counter_uniform(p_.seed, k, 0, kStreamInitX),
                        sz.y * counter_uniform(p_.seed, k, 0, kStreamInitY),
                        sz.z * counter_uniform(p_.seed, k, 0, kStreamInitZ)};
  }
  std::vector<Point> placed;
  std::vector<char> ok, outside;
  e_.place_many(candidates(xs), kPlaceSteps, {}, placed, ok, &outside);
  std::size_t dropped = 0, nout = 0;
  Vec3 example;
  for (std::size_t k = 0; k < xs.size(); ++k) {
    if (ok[k]) {
      e_.add(placed[k], init_type(k));
    } else if (outside[k]) {
      if (nout++ == 0) example = placed[k].x;
    } else {
      ++dropped;
    }
  }
  if (nout)
    throw InputError("sizing field " + quote(sizing_->name()) + " does not cover the surface: " +
                     std::to_string(nout) + " particle(s) on F = " + engine_fmt(p_.iso) + " lie outside its box " +
                     engine_fmt(sizing_->bounds().lo) + " - " + engine_fmt(sizing_->bounds().hi) + ", e.g. at " +
                     engine_fmt(example));
  res.dropped_init = dropped;
  if (e_.particles().empty())
    throw InputError("no surface found: none of the " + std::to_string(xs.size()) + " initial points reached F = " +
                     engine_fmt(p_.iso) + " within " + std::to_string(kPlaceSteps) + " Newton steps (" +
                     field_.describe() + "); check the isovalue and the seeds");
  if (!p_.count) e_.set_anchors_from_particles();
  if (p_.count) fill_to_count();
}

// Fixed count: trim, or add children next to the first particles until the
// count is reached.
void SurfaceRun::fill_to_count() {
  auto& parts = e_.particles();
  if (parts.size() > p_.count) parts.resize(p_.count);
  for (int round = 0; parts.size() < p_.count; ++round) {
    if (round > kCountRounds)
      throw InputError("could not place " + std::to_string(p_.count) + " particles on the surface (got " +
                       std::to_string(parts.size()) + ")");
    const std::size_t need = std::min(parts.size(), p_.count - parts.size());
    std::vector<Engine::Candidate> kids(need);
    for (std::size_t i = 0; i < need; ++i) {
      const auto& q = parts[i];
      const double u = counter_uniform(p_.seed, q.id, std::uint64_t(round), kStreamSplitDir);
      kids[i].x = q.p.x + c_.split_offset(q.p, u, kCountChildOffset * q.spacing);
    }
    std::vector<Point> placed;
    std::vector<char> ok;
    e_.place_many(kids, kPlaceSteps, {}, placed, ok);
    for (std::size_t i = 0; i < need; ++i)
      if (ok[i]) e_.add(placed[i], p_.quads ? std::uint8_t(1 - parts[i].type) : std::uint8_t(0));
  }
}

ParticleResult SurfaceRun::run(const std::vector<Vec3>& seeds) {
  ParticleResult res;
  const bool curvature_mode = sizing_ == nullptr;
  Stopwatch sw;
  int levels = curvature_mode ? coarse_levels(p_.spacing) : 0;
  double lattice_step = 0;
  if (p_.init_lattice && seeds.empty()) {
    if (curvature_mode)
      lattice_step = kLatticePerSpacing * p_.spacing * std::ldexp(1.0, levels);
    else
      lattice_step = kLatticePerSpacing * (p_.coarse_to_fine && p_.count == 0
                                               ? (p_.coarse_start > 0 ? p_.coarse_start
                                                                      : kCoarseVoxels * field_.resolution())
                                               : sizing_->min_value());
  }
  initialise(seeds, lattice_step, res);
  res.seconds_init = sw.seconds();

  if (!curvature_mode && p_.coarse_to_fine && p_.count == 0) {  // the median h over the initial particles
    std::vector<double> h;
    for (const auto& q : e_.particles()) h.push_back(q.attr);
    std::nth_element(h.begin(), h.begin() + std::ptrdiff_t(h.size() / 2), h.end());
    levels = coarse_levels(h[h.size() / 2]);
  }
  e_.set_scale(std::ldexp(1.0, levels));
  e_.refresh_spacings();
  res.levels = levels + 1;
  if (p_.seed_thinning > 0 && !seeds.empty()) res.thinned = e_.thin_particles(p_.seed_thinning);

  bool conv = false;
  for (int level = levels; level >= 0; --level) {
    if (level == 0 && levels > 0) {  // from here on every anchor keeps a particle near it
      e_.guard_anchors();
      res.refilled += e_.refill_holes();
    }
    const std::string label =
        levels > 0 ? "level " + std::to_string(levels - level + 1) + "/" + std::to_string(levels + 1) : "relax";
    e_.set_tolerance(level > 0 ? std::max(p_.tolerance, p_.coarse_tolerance) : p_.tolerance);
    e_.set_population_tolerance(level > 0 ? std::max(p_.population_tolerance, p_.coarse_population_tolerance)
                                          : p_.population_tolerance);
    const Engine::LevelResult lr = e_.relax(label, p_.count != 0);
    conv = lr.converged;
    res.iterations += lr.iterations;
    res.splits += lr.splits;
    res.deletions += lr.deletions;
    res.refilled += lr.refilled;
    debug(label + ": " + std::to_string(e_.particles().size()) + " particles, " + std::to_string(res.iterations) +
          " iterations so far" + (conv ? "" : " (not converged)"));
    if (level > 0) {
      Stopwatch sp;
      e_.split_all();
      e_.stats().seconds_population += sp.seconds();
    }
  }
  res.converged = conv;

  Stopwatch sf;
  const double e = e_.measure();
  const auto& parts = e_.particles();
  const std::size_t n = parts.size();
  e_.export_points(res.positions, res.normals, res.energy, res.spacing);
  if (p_.quads) {
    res.types.resize(n);
    for (std::size_t i = 0; i < n; ++i) res.types[i] = parts[i].type;
  }
  res.curvature.resize(n);
  std::uint64_t nb = 0;
  double ideal = 0;
  for (const auto& q : parts) {
    nb += std::uint64_t(q.neighbours);
    ideal += e_.ideal_energy(q);
  }
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, n, 64), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      Vec3 g;
      Mat3 h;
      field_.evaluate(res.positions[i], g, h);
      res.curvature[i] = curvedness_of(g, h);
    }
  });
  EngineStats& st = e_.stats();
  st.field_evaluations += n;
  res.energy_final = e;
  res.energy_ideal = ideal;
  res.mean_neighbours = n ? double(nb) / double(n) : 0.0;
  res.final_spacing = curvature_mode ? e_.planar_spacing() : e_.scale();
  res.field_evaluations = st.field_evaluations;
  res.particle_updates = st.updates;
  res.list_builds = st.list_builds;
  res.engine = st;
  res.seconds_relax = st.seconds_relax;
  res.seconds_population = st.seconds_population;
  res.seconds_finish = sf.seconds();
  return res;
}

}  // namespace

ParticleResult distribute_particles(const ScalarField& field, const std::vector<Vec3>& seeds,
                                    const SizingField* sizing, const ParticleParams& params) {
  const Box dom = field.domain();
  if (dom.empty()) throw InputError("distribute_particles: the field " + field.describe() + " has an empty domain");
  const double diag = norm(dom.size());
  if (!sizing && (!(params.spacing > 0) || !std::isfinite(params.spacing)))
    throw UsageError("spacing must be > 0 world units, got " + engine_fmt(params.spacing));
  if (!sizing && params.spacing > diag)
    throw UsageError("spacing " + engine_fmt(params.spacing) + " is larger than the domain's diagonal " +
                     engine_fmt(diag) + " (world units); expected a spacing well below the size of the surface");
  if (!(params.density >= 0) || !std::isfinite(params.density))
    throw UsageError("density must be >= 0 particles per radian, got " + engine_fmt(params.density));
  if (!(params.alpha_cap >= 1)) throw UsageError("alpha cap must be >= 1, got " + engine_fmt(params.alpha_cap));
  if (!(params.tolerance > 0)) throw UsageError("tolerance must be > 0, got " + engine_fmt(params.tolerance));
  if (!(params.coarse_tolerance >= 0))
    throw UsageError("coarse tolerance must be >= 0, got " + engine_fmt(params.coarse_tolerance));
  if (!(params.coarse_population_tolerance >= 0))
    throw UsageError("coarse population tolerance must be >= 0, got " +
                     engine_fmt(params.coarse_population_tolerance));
  if (!(params.population_tolerance >= 0))
    throw UsageError("population tolerance must be >= 0, got " + engine_fmt(params.population_tolerance));
  if (params.max_iters < 1) throw UsageError("max iterations must be >= 1, got " + std::to_string(params.max_iters));
  if (params.population_interval < 1)
    throw UsageError("population interval must be >= 1, got " + std::to_string(params.population_interval));
  if (seeds.empty() && params.init_count == 0) throw UsageError("init count must be >= 1 when no seeds are given");
  if (params.reproject_steps < 1)
    throw UsageError("reprojection steps must be >= 1, got " + std::to_string(params.reproject_steps));
  if (!(params.seed_thinning >= 0 && params.seed_thinning < 2))
    throw UsageError("seed thinning must be in [0, 2) spacings, got " + engine_fmt(params.seed_thinning));
  if (!(params.settled_move >= 0 && params.settled_move < 1))
    throw UsageError("settled move must be in [0, 1) spacings, got " + engine_fmt(params.settled_move));
  if (!(params.step_factor > 1))
    throw UsageError("step factor must be > 1, got " + engine_fmt(params.step_factor));
  SurfaceRun run(field, sizing, params);
  return run.run(seeds);
}

}  // namespace pm
