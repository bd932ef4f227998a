// distribute_multi_particles: the junction configuration of the one particle
// engine (pm/sample/engine.h with pm/sample/junction_constraint.h): seeds
// sorted into cells, thinned and projected; quadruple points culled and
// fixed; curves relaxed against the fixed points, then fixed; surfaces
// relaxed against both; then junction repair and the result.
#include "pm/sample/multiparticles.h"

#include <tbb/blocked_range.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/parallel.h"
#include "pm/sample/engine.h"
#include "pm/sample/junction_constraint.h"
#include "pm/volume/mcinit.h"

namespace pm {
namespace {

using Engine = ParticleEngine<JunctionConstraint>;
using Point = JunctionConstraint::Point;
using engine_constants::kPlaceSteps;

constexpr double kDefaultTolerancePerResolution = 1e-6;  // projection tolerance, × the fields' resolution
constexpr double kRepairDistance = 0.25;  // surface particles of two interfaces closer than h/4 ...
constexpr double kRepairLanding = 0.5;    // ... become one junction particle landing within h/2 of their middle
constexpr double kRepairClearance = 0.5;  // ... unless a curve or point particle lies within h/2 of it
constexpr int kLevels = 3;                // 0: quadruple points, 1: triple curves, 2: surfaces

int level_of(const JunctionCell& c) { return 4 - c.count; }

struct Seed {  // a seed of one cell
  Vec3 x;
  std::int32_t cell;
  std::size_t order = 0;  // index into what it was made from
};

class MultiRun {
 public:
  MultiRun(const MaterialSet& m, const Box& domain, double resolution, const SizingField* sizing,
           const MultiParticleParams& p)
      : m_(m), sizing_(sizing), p_(p),
        c_(m, domain, p.projection_tolerance > 0 ? p.projection_tolerance
                                                  : kDefaultTolerancePerResolution * resolution) {}

  MultiParticleResult run(const std::vector<JunctionSeed>& seeds);

 private:
  EngineParams engine_params() const {
    EngineParams e;
    copy_relax_params(p_, e);
    e.sizing_mode = true;
    e.sizing = sizing_;
    e.spacing = p_.spacing;
    e.keep_covered = true;
    // End a level once its population is stationary, then polish: frog5
    // (DECIMATE 1, seed thinning 0.8) 74 -> 51 surface sweeps, 61 -> 50
    // updates per particle; rr means of the five ch6 data sets within 0.0006.
    e.population_balance = true;
    // Population checks after 8, 16, 32 sweeps, then every 50, as on a
    // surface: frog5 4.2 -> 2.9 M updates (9.8 -> 7.7 s), interface rr mean
    // 0.9631 -> 0.9634, rr min 0.50 -> 0.44 (target >= 0.30).
    e.first_population_interval = engine_constants::kFirstPopulationInterval;
    // The sizing field of a label map is strongly graded (HMIN near the
    // junctions, many times that inside large materials), so the bins, as
    // wide as the largest reach, hold many particles a small one never sees:
    // gather from the fine grid. frog5: surfaces 6.8 -> 5.2 s (2.9 -> 3.1 M
    // updates), interface rr min 0.435 -> 0.547, means within 0.0015.
    e.fine_bins = true;
    return e;
  }
  double spacing_at(const Vec3& x) const {
    double h = 0;
    if (!sizing_) return p_.spacing;
    return sizing_->sample(x, h) && h > 0 ? h : sizing_->min_value();
  }
  void thin(std::vector<Seed>& seeds, double fraction) const;
  // Place seeds on their cells; returns the placed points of those that made it.
  std::vector<Point> place(Engine& e, const std::vector<Seed>& seeds, std::size_t& failed) const;
  std::size_t repair_junctions(Engine& e, std::size_t& merged, std::size_t& corners, std::size_t& dropped);

  const MaterialSet& m_;
  const SizingField* sizing_;
  MultiParticleParams p_;
  JunctionConstraint c_;
};

// Greedy thinning in the seeds' order: drop a seed closer than fraction × h
// to a kept one of the same cell.
void MultiRun::thin(std::vector<Seed>& seeds, double fraction) const {
  if (seeds.empty() || fraction <= 0) return;
  std::vector<Vec3> xs(seeds.size());
  std::vector<double> radius(seeds.size());
  std::vector<std::int32_t> group(seeds.size());
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    xs[i] = seeds[i].x;
    radius[i] = fraction * spacing_at(seeds[i].x);
    group[i] = seeds[i].cell;
  }
  std::vector<Seed> kept;
  for (std::size_t i : thin_points(xs, radius, group)) kept.push_back(seeds[i]);
  seeds.swap(kept);
}

std::vector<Point> MultiRun::place(Engine& e, const std::vector<Seed>& seeds, std::size_t& failed) const {
  std::vector<Engine::Candidate> cands(seeds.size());
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    cands[i].x = seeds[i].x;
    cands[i].like = c_.of_cell(seeds[i].cell);
  }
  std::vector<Point> placed, good;
  std::vector<char> ok;
  e.place_many(cands, p_.seed_project_steps, {}, placed, ok);
  failed = 0;
  for (std::size_t i = 0; i < seeds.size(); ++i)
    if (ok[i])
      good.push_back(placed[i]);
    else
      ++failed;
  return good;
}

// After the surfaces: two surface particles of different interfaces that
// share a material ({a,b}, {a,c}) closer than a quarter spacing sit where the
// interfaces meet on a triple curve that the curve level did not sample
// (tightening moves junctions; seeds are only near most of them). Such a
// pair is replaced by one particle projected onto the triple junction
// {a,b,c}, when the projection lands within half a spacing and no curve or
// point particle is already there. Otherwise the Delaunay mesh gets a sliver
// spanning the two interfaces. Sequential in bin order: deterministic.
//
// Before that, the curves alike: two particles of different triple curves
// that share two materials ({a,b,c}, {a,b,d}) closer than a quarter spacing
// sit where the curves meet at a quadruple point that the point level did
// not sample (frog15 after tightening: two curve particles 0.002 mm apart,
// four triangles of radius ratio 0.002). The pair becomes one particle on
// the quadruple junction {a,b,c,d} when the projection lands within half a
// spacing and no point particle is already that close; otherwise the later
// one of the pair is dropped (the curves pass within h/4 of each other
// there, and one vertex serves both).
std::size_t MultiRun::repair_junctions(Engine& e, std::size_t& merged, std::size_t& corners, std::size_t& dropped) {
  merged = corners = dropped = 0;
  e.rebin();
  auto& parts = e.particles();
  const std::size_t n = parts.size();
  std::vector<char> gone(n, 0);
  std::vector<Point> added;
  std::vector<char> on_junction;  // added[k]: 2 a quadruple point, 1 a triple-junction particle, 0 a merged pair
  Probe pr;
  // Whether a particle of `count` or more materials, given or added, lies within r of x.
  auto near_junction = [&](const Vec3& x, double r, int count) {
    bool near = false;
    e.for_each_near(x, r, [&](std::size_t q) { near = near || c_.cell(parts[q].p).count >= count; });
    for (std::size_t k = 0; k < added.size(); ++k)
      near = near || (on_junction[k] >= count - 2 && norm2(added[k].x - x) < r * r);
    return near;
  };
  // Calls f(i, j, hmin) for the pairs of particles of `count` materials
  // closer than kRepairDistance times the smaller spacing hmin, neither gone,
  // i in bin order and j near it.
  auto close_pairs = [&](int count, const auto& f) {
    for (std::size_t i = 0; i < n; ++i) {
      if (gone[i] || c_.cell(parts[i].p).count != count) continue;
      e.for_each_near(parts[i].p.x, kRepairDistance * parts[i].spacing, [&](std::size_t j) {
        if (gone[i] || j == i || gone[j] || c_.cell(parts[j].p).count != count) return;
        const double hmin = std::min(parts[i].spacing, parts[j].spacing);
        if (norm2(parts[j].p.x - parts[i].p.x) < kRepairDistance * kRepairDistance * hmin * hmin) f(i, j, hmin);
      });
    }
  };
  // The cell of the materials of i's and j's cells together, if they make
  // one of `count` materials (-1 otherwise).
  auto joint_cell = [&](std::size_t i, std::size_t j, std::size_t count) {
    const JunctionCell& ci = c_.cell(parts[i].p);
    const JunctionCell& cj = c_.cell(parts[j].p);
    std::vector<int> mats(ci.m.begin(), ci.m.begin() + ci.count);
    for (int t = 0; t < cj.count; ++t)
      if (!ci.contains(cj.m[std::size_t(t)])) mats.push_back(cj.m[std::size_t(t)]);
    return mats.size() == count ? c_.cell_index(make_cell(mats)) : std::int32_t(-1);
  };
  auto landed = [&](const Vec3& q, const Vec3& mid, double hmin) {
    return (!sizing_ || sizing_->covers(q)) && norm2(q - mid) < kRepairLanding * kRepairLanding * hmin * hmin;
  };
  close_pairs(3, [&](std::size_t i, std::size_t j, double hmin) {
    if (parts[j].p.s.cell == parts[i].p.s.cell) return;
    const std::int32_t cell = joint_cell(i, j, 4);
    if (cell < 0) return;  // not two curves of one quadruple point
    const Vec3 mid = (parts[i].p.x + parts[j].p.x) * 0.5;
    Point q;
    if (!near_junction(mid, kRepairClearance * hmin, 4) && c_.place(mid, c_.of_cell(cell), kPlaceSteps, hmin, q, pr) && landed(q.x, mid, hmin)) {
      added.push_back(q);
      on_junction.push_back(2);
      ++corners;
      gone[i] = gone[j] = 1;
      return;
    }
    gone[j] = 1;  // one vertex for both curves
    ++dropped;
  });
  close_pairs(2, [&](std::size_t i, std::size_t j, double hmin) {
    const Vec3 mid = (parts[i].p.x + parts[j].p.x) * 0.5;
    Point q;
    if (parts[j].p.s.cell == parts[i].p.s.cell) {
      // One interface folding sharply between them (normals 90 degrees or
      // more apart: the normal weighting hides them from each other): one
      // particle at their middle, projected onto the interface.
      if (!c_.place(mid, parts[i].p, kPlaceSteps, hmin, q, pr) || !landed(q.x, mid, hmin)) return;
      added.push_back(q);
      on_junction.push_back(0);
      ++merged;
      gone[i] = gone[j] = 1;
      return;
    }
    const std::int32_t cell = joint_cell(i, j, 3);
    if (cell < 0) return;  // disjoint pairs: not one triple junction
    if (!c_.place(mid, c_.of_cell(cell), kPlaceSteps, hmin, q, pr) || !landed(q.x, mid, hmin) ||
        near_junction(q.x, kRepairClearance * spacing_at(q.x), 3))
      return;
    added.push_back(q);
    on_junction.push_back(1);
    gone[i] = gone[j] = 1;
  });
  e.stats().field_evaluations += pr.evaluations;
  if (added.empty() && dropped == 0) return 0;
  std::size_t k = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (!gone[i]) parts[k++] = parts[i];
  parts.resize(k);
  for (const Point& q : added) e.add(q, 0, true);
  return added.size() - merged - corners;
}

MultiParticleResult MultiRun::run(const std::vector<JunctionSeed>& seeds) {
  MultiParticleResult res;
  // Seeds -> cells (material indices), per level.
  std::map<int, int> index_of;
  for (std::size_t i = 0; i < m_.labels.size(); ++i) index_of[m_.labels[i]] = int(i);
  std::array<std::vector<Seed>, kLevels> by_level;
  for (std::size_t k = 0; k < seeds.size(); ++k) {
    const JunctionSeed& s = seeds[k];
    if (!is_finite(s.x))
      throw InputError("seed " + std::to_string(k) + " is not finite: " + engine_fmt(s.x) +
                       "; expected finite world coordinates");
    if (s.count < 2 || s.count > 4)
      throw InputError("seed " + std::to_string(k) + " has " + std::to_string(s.count) +
                       " labels; expected 2, 3 or 4");
    const int level = 4 - s.count;
    ++res.levels[std::size_t(level)].seeds;
    std::vector<int> mats;
    bool known = true;
    for (int q = 0; q < s.count; ++q) {
      auto it = index_of.find(s.labels[std::size_t(q)]);
      if (it == index_of.end()) {
        known = false;
        break;
      }
      mats.push_back(it->second);
    }
    if (!known) {
      ++res.levels[std::size_t(level)].seeds_unknown;
      continue;
    }
    by_level[std::size_t(level)].push_back({s.x, c_.cell_index(make_cell(mats)), k});
  }
  c_.finish_cells();
  Engine e(c_, engine_params());

  const char* names[kLevels] = {"points", "curves", "surfaces"};
  for (int level = 0; level < kLevels; ++level) {
    if (level == 2 && !p_.surfaces) break;
    MultiLevelStats& st = res.levels[std::size_t(level)];
    Stopwatch sw;
    std::vector<Seed>& cands = by_level[std::size_t(level)];
    const std::size_t given = cands.size();
    if (level > 0) thin(cands, level == 2 ? p_.surface_seed_thinning : p_.seed_thinning);
    const std::size_t after_thin = cands.size();
    std::vector<Point> placed = place(e, cands, st.seeds_failed);
    if (level == 0) {  // cull duplicates of one quadruple point
      std::vector<Seed> good;
      for (std::size_t i = 0; i < placed.size(); ++i) good.push_back({placed[i].x, placed[i].s.cell, i});
      thin(good, p_.cull_fraction);
      st.seeds_culled = placed.size() - good.size();
      std::vector<Point> kept;
      for (const Seed& g : good) kept.push_back(placed[g.order]);
      placed.swap(kept);
    } else {
      st.seeds_culled = given - after_thin;
    }
    for (const Point& q : placed) e.add(q);
    debug("level " + std::to_string(level) + ": " + std::to_string(placed.size()) + " particles from " +
          std::to_string(given) + " seeds");
    if (level > 0 && e.active_count() > 0) {
      const Engine::LevelResult lr = e.relax(names[level], false);
      st.iterations = lr.iterations;
      st.converged = lr.converged;
      st.splits = lr.splits;
      st.deletions = lr.deletions;
      st.energy_final = e.measure();
      for (const auto& q : e.particles())
        if (!q.fixed) st.energy_ideal += e.ideal_energy(q);
    }
    std::vector<char> has(c_.cells().size(), 0);
    st.particles = 0;
    for (auto& q : e.particles())
      if (!q.fixed) {
        ++st.particles;
        has[std::size_t(q.p.s.cell)] = 1;
        q.fixed = true;
      }
    for (char h : has) st.cells += h ? 1 : 0;
    st.seconds = sw.seconds();
  }
  const std::size_t surfaces =
      p_.surfaces ? res.levels[2].particles : res.levels[1].particles + res.levels[0].particles;
  if (surfaces == 0) {
    std::string labels;
    for (int l : m_.labels) labels += (labels.empty() ? "" : ",") + std::to_string(l);
    throw InputError("no material interface found: none of the " + std::to_string(seeds.size()) +
                     " seeds reached a junction of the materials " + labels +
                     " (do the materials touch? are the seeds from the same label map?)");
  }

  if (p_.surfaces && p_.repair_junctions)
    res.junction_repairs = repair_junctions(e, res.close_pairs_merged, res.corner_repairs, res.curve_pairs_dropped);

  // Output, level by level, in a deterministic order (level, then bin order).
  e.stable_order([&](const Engine::Particle& q) { return level_of(c_.cell(q.p)); });
  e.export_points(res.positions, res.normals, res.energy, res.spacing);
  const auto& parts = e.particles();
  const std::size_t n = parts.size();
  res.junction.resize(n);
  res.labels.resize(n);
  res.residual.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& q = parts[i];
    const JunctionCell& c = c_.cell(q.p);
    if (c.count != 2) res.normals[i] = Vec3{};
    res.junction[i] = c.count;
    std::array<int, 4> l{{-1, -1, -1, -1}};
    for (int k = 0; k < c.count; ++k) l[std::size_t(k)] = m_.labels[std::size_t(c.m[std::size_t(k)])];
    std::sort(l.begin(), l.begin() + std::clamp(c.count, 0, 4));
    res.labels[i] = l;
    res.residual[i] = q.p.s.residual;
    res.max_residual = std::max(res.max_residual, q.p.s.residual);
  }
  res.engine = e.stats();
  res.field_evaluations = res.engine.field_evaluations;
  return res;
}

}  // namespace

std::vector<JunctionSeed> junction_seeds_from_mesh(const Mesh& m, const std::string& what) {
  const char* names[] = {"junction", "label_a", "label_b", "label_c", "label_d"};
  for (const char* nm : names)
    if (!m.vertex_scalars.count(nm))
      throw InputError(quote(what) + ": missing vertex property \"" + nm +
                       "\"; expected junction seeds as written by `mcinit --junctions` (junction, label_a..label_d)");
  const auto& jn = m.vertex_scalars.at("junction");
  const std::vector<double>* lab[4] = {&m.vertex_scalars.at("label_a"), &m.vertex_scalars.at("label_b"),
                                       &m.vertex_scalars.at("label_c"), &m.vertex_scalars.at("label_d")};
  std::vector<JunctionSeed> out(m.vertices.size());
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    JunctionSeed& s = out[i];
    s.x = m.vertices[i];
    if (!is_finite(s.x))
      throw InputError(quote(what) + ": vertex " + std::to_string(i) + " is not finite: " + engine_fmt(s.x));
    const double j = jn[i];
    if (!(j == 2 || j == 3 || j == 4))
      throw InputError(quote(what) + ": vertex " + std::to_string(i) + " has junction " + engine_fmt(j) +
                       "; expected 2, 3 or 4");
    s.count = int(j);
    for (int k = 0; k < s.count; ++k) {
      const double v = (*lab[k])[i];
      if (!(v >= 0) || v != std::floor(v) || v > 2147483647.0)
        throw InputError(quote(what) + ": vertex " + std::to_string(i) + " has label " + engine_fmt(v) +
                         "; expected a non-negative integer");
      s.labels[std::size_t(k)] = int(v);
    }
    std::sort(s.labels.begin(), s.labels.begin() + s.count);
    for (int k = 1; k < s.count; ++k)
      if (s.labels[std::size_t(k)] == s.labels[std::size_t(k - 1)])
        throw InputError(quote(what) + ": vertex " + std::to_string(i) + " repeats label " +
                         std::to_string(s.labels[std::size_t(k)]));
  }
  return out;
}

std::vector<JunctionSeed> junction_seeds_from_materials(const MaterialSet& m, double spacing) {
  if (m.fields.size() < 2)
    throw InputError("junction seeds need at least 2 materials, got " + std::to_string(m.fields.size()));
  Box dom = m.fields[0]->domain();
  double res = m.fields[0]->resolution();
  for (const auto& f : m.fields) {
    const Box b = f->domain();
    for (int a = 0; a < 3; ++a) {
      dom.lo[a] = std::max(dom.lo[a], b.lo[a]);
      dom.hi[a] = std::min(dom.hi[a], b.hi[a]);
    }
    res = std::min(res, f->resolution());
  }
  if (dom.empty() || dom.lo.x >= dom.hi.x || dom.lo.y >= dom.hi.y || dom.lo.z >= dom.hi.z)
    throw InputError("the materials' domains do not overlap; expected volumes covering the same box");
  const double h = spacing > 0 ? spacing : res;
  Dims d;
  std::size_t n[3];
  for (int a = 0; a < 3; ++a) {
    const double len = dom.hi[a] - dom.lo[a];
    if (len / h > 511) throw InputError("seed grid too fine: " + engine_fmt(len / h) + " nodes along an axis (at most 512)");
    n[a] = std::size_t(std::floor(len / h + 1e-9)) + 1;
  }
  d.nx = n[0];
  d.ny = n[1];
  d.nz = n[2];
  Volume v(VoxelType::i32, d, Geometry::with_spacing(h, h, h, dom.lo));
  std::int32_t* data = v.data<std::int32_t>();
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, d.nz), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k)
      for (std::size_t j = 0; j < d.ny; ++j)
        for (std::size_t i = 0; i < d.nx; ++i) {
          const Vec3 x = dom.lo + Vec3{double(i) * h, double(j) * h, double(k) * h};
          std::size_t best = 0;
          double bf = -m.fields[0]->value(x);
          for (std::size_t q = 1; q < m.fields.size(); ++q) {
            const double f = -m.fields[q]->value(x);
            if (f > bf) {
              bf = f;
              best = q;
            }
          }
          data[v.index(i, j, k)] = m.labels[best];
        }
  });
  JunctionResult jr;
  try {
    jr = junction_seeds(v);
  } catch (const InputError& e) {
    throw InputError(std::string("junction seeds from the materials' argmax grid: ") + e.what());
  }
  return junction_seeds_from_mesh(jr.seeds, "argmax grid seeds");
}

MultiParticleResult distribute_multi_particles(const MaterialSet& m, const std::vector<JunctionSeed>& seeds,
                                               const SizingField* sizing, const MultiParticleParams& p) {
  if (m.fields.size() < 2 || m.labels.size() != m.fields.size())
    throw InputError("multi-material sampling needs at least 2 materials, got " + std::to_string(m.fields.size()));
  if (!sizing && (!(p.spacing > 0) || !std::isfinite(p.spacing)))
    throw UsageError("spacing must be > 0 world units, got " + engine_fmt(p.spacing));
  if (sizing && !(sizing->min_value() > 0))
    throw InputError("sizing field " + quote(sizing->name()) + " has h <= 0 (min " + engine_fmt(sizing->min_value()) +
                     "); expected h > 0 world units");
  if (!(p.tolerance > 0)) throw UsageError("tolerance must be > 0, got " + engine_fmt(p.tolerance));
  if (p.max_iters < 1) throw UsageError("max iterations must be >= 1, got " + std::to_string(p.max_iters));
  if (p.population_interval < 1)
    throw UsageError("population interval must be >= 1, got " + std::to_string(p.population_interval));
  if (!(p.population_tolerance >= 0))
    throw UsageError("population tolerance must be >= 0, got " + engine_fmt(p.population_tolerance));
  if (p.seed_project_steps < 1)
    throw UsageError("seed projection steps must be >= 1, got " + std::to_string(p.seed_project_steps));
  if (seeds.empty()) throw InputError("no junction seeds given; expected mcinit --junctions points or a label map");
  const Box dom = m.domain();
  const double resolution = m.resolution();
  if (dom.lo.x >= dom.hi.x || dom.lo.y >= dom.hi.y || dom.lo.z >= dom.hi.z)
    throw InputError("the materials' domains do not overlap (intersection " + engine_fmt(dom.lo) + " - " + engine_fmt(dom.hi) +
                     "); expected volumes covering the same box");
  if (sizing) {  // like particles: a sizing field that misses the junctions is the wrong field
    std::size_t nout = 0;
    Vec3 example;
    for (const JunctionSeed& sd : seeds)
      if (is_finite(sd.x) && !sizing->covers(sd.x) && nout++ == 0) example = sd.x;
    if (nout)
      throw InputError("sizing field " + quote(sizing->name()) + " does not cover the junctions: " +
                       std::to_string(nout) + " of " + std::to_string(seeds.size()) + " seeds lie outside its box " +
                       engine_fmt(sizing->bounds().lo) + " - " + engine_fmt(sizing->bounds().hi) + ", e.g. at " +
                       engine_fmt(example) + "; expected the sizing field of these materials, on their grid");
  }
  if (!sizing && p.spacing > norm(dom.size()))
    throw UsageError("spacing " + engine_fmt(p.spacing) + " is larger than the domain's diagonal " + engine_fmt(norm(dom.size())));
  if (p.reproject_steps < 1)
    throw UsageError("reprojection steps must be >= 1, got " + std::to_string(p.reproject_steps));
  if (!(p.settled_move >= 0 && p.settled_move < 1))
    throw UsageError("settled move must be in [0, 1) spacings, got " + engine_fmt(p.settled_move));
  if (!(p.step_factor > 1))
    throw UsageError("step factor must be > 1, got " + engine_fmt(p.step_factor));
  MultiRun run(m, dom, resolution, sizing, p);
  return run.run(seeds);
}

Mesh multi_particles_mesh(const MultiParticleResult& r) {
  Mesh m;
  m.vertices = r.positions;
  m.normals = r.normals;
  const std::size_t n = r.positions.size();
  std::vector<double> jn(n), la(n), lb(n), lc(n), ld(n);
  for (std::size_t i = 0; i < n; ++i) {
    jn[i] = r.junction[i];
    la[i] = r.labels[i][0];
    lb[i] = r.labels[i][1];
    lc[i] = r.labels[i][2];
    ld[i] = r.labels[i][3];
  }
  m.vertex_scalars["junction"] = jn;
  m.vertex_scalars["label_a"] = la;
  m.vertex_scalars["label_b"] = lb;
  m.vertex_scalars["label_c"] = lc;
  m.vertex_scalars["label_d"] = ld;
  m.vertex_scalars["spacing"] = r.spacing;
  m.vertex_scalars["energy"] = r.energy;
  m.vertex_scalars["residual"] = r.residual;
  return m;
}

}  // namespace pm
