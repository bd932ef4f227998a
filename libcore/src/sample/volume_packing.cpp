#include "pm/sample/volume_packing.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/sample/volume_constraint.h"

namespace pm {
namespace {

constexpr int kMaxOctreeDepth = 12;     // cubes down to 1/4096 of the box
// Seed lattice spacing / h. A close packing at nearest distance h has
// √2 / h³ points per volume (simple cubic spacing h / 2^(1/6) = 0.89 h); the
// engine's 12-neighbour equilibrium settles about 1.4 times denser
// (measured on the brain mask: 123k seeds at 0.89 h grew to 171k), so seeds
// start at that density and population control has little left to do.
constexpr double kSeedSpacing = 0.8;

struct Seeder {
  const ScalarField& field;
  double iso;
  const VolumePackParams& p;
  std::vector<Vec3>& out;
  std::vector<double>& h_out;

  bool size_at(const Vec3& x, double& h) const {
    if (!p.sizing) {
      h = p.spacing;
      return true;
    }
    return p.sizing->sample(x, h);
  }
  // Cubes are split while they are larger than twice h at their centre (or,
  // near the region's boundary, while the centre is outside but the cube may
  // still reach inside: |F - iso| / |∇F| below the half diagonal). A leaf of
  // edge e then holds a k³ lattice of spacing e / k ≈ kSeedSpacing × h; only
  // the lattice points inside F < iso are kept.
  void visit(const Vec3& lo, double edge, int depth) {
    const Vec3 c = lo + Vec3{edge, edge, edge} * 0.5;
    double h = 0;
    const bool known = size_at(c, h) && h > 0;
    Vec3 g;
    const double f = field.value_gradient(c, g);
    if (!std::isfinite(f)) return;
    const double gn = norm(g);
    const double half_diag = 0.8660254037844386 * edge;
    // Whole cube outside when F - iso exceeds a slope bound times the half
    // diagonal. The bound is max(2, 2 |∇F(centre)|): 2 holds for distance
    // fields and the material regions (a difference of two distances), whose
    // gradient can vanish at a centre (a ball's middle) while F still drops
    // at the full rate a little away; twice the centre's slope covers steeper
    // fields that vary smoothly across the cube.
    if (f >= iso && f - iso > std::max(2.0, 2 * gn) * half_diag) return;
    const double want = known ? h : edge;
    if (depth < kMaxOctreeDepth && (edge > 2 * want || (f >= iso && edge > want))) {
      const double e2 = edge / 2;
      for (int k = 0; k < 8; ++k)
        visit(lo + Vec3{double(k & 1), double((k >> 1) & 1), double(k >> 2)} * e2, e2, depth + 1);
      return;
    }
    if (!known) return;
    // Body-centred cubic: cubes of edge b hold 2 points (density 2 / b³, equal
    // to the seeds' 1 / (kSeedSpacing h)³ at b = 2^(1/3) kSeedSpacing h); its
    // Delaunay tetrahedra are the well-shaped Sommerville tetrahedra.
    const double b = 1.2599210498948732 * kSeedSpacing * h;
    const int k = std::max(1, int(std::lround(edge / b)));
    const double step = edge / k;
    for (int z = 0; z < k; ++z)
      for (int y = 0; y < k; ++y)
        for (int x = 0; x < k; ++x)
          for (int half = 0; half < 2; ++half) {
            const double o = half ? 0.75 : 0.25;
            const Vec3 q = lo + Vec3{x + o, y + o, z + o} * step;
            if (!field.domain().contains(q) || !(field.value(q) < iso)) continue;
            double hq = h;
            size_at(q, hq);
            out.push_back(q);
            h_out.push_back(hq);
          }
  }
};

void add_stats(EngineStats& a, const EngineStats& b) {
  add_update_counters(a, b);
  a.list_builds += b.list_builds;
  if (a.first_failure.empty()) a.first_failure = b.first_failure;
  a.seconds_relax += b.seconds_relax;
  a.seconds_population += b.seconds_population;
}

}  // namespace

VolumePackResult pack_volume(const ScalarField& field, double iso, const std::vector<Vec3>& fixed,
                             const VolumePackParams& p, int label) {
  if (!p.sizing && !(p.spacing > 0))
    throw UsageError("volume packing: spacing " + engine_fmt(p.spacing) + " must be > 0 (world units) without a sizing field");
  if (!(p.seed_clearance > 0 && p.seed_clearance < 2))
    throw UsageError("volume packing: seed clearance " + engine_fmt(p.seed_clearance) + " must lie in (0, 2)");
  if (!(p.tolerance > 0)) throw UsageError("volume packing: tolerance must be > 0");
  if (p.max_iters < 1) throw UsageError("volume packing: max iterations must be >= 1");

  // The region's box: the boundary particles' box (they enclose it), else
  // the field's domain; clipped to the sizing field's box.
  Box box;
  if (!fixed.empty()) {
    for (const Vec3& x : fixed) box.extend(x);
  } else {
    box = field.domain();
  }
  if (p.sizing) {
    const Box& sb = p.sizing->bounds();
    box.lo = Vec3{std::max(box.lo.x, sb.lo.x), std::max(box.lo.y, sb.lo.y), std::max(box.lo.z, sb.lo.z)};
    box.hi = Vec3{std::min(box.hi.x, sb.hi.x), std::min(box.hi.y, sb.hi.y), std::min(box.hi.z, sb.hi.z)};
  }
  const Vec3 ext = box.hi - box.lo;
  const double edge = std::max({ext.x, ext.y, ext.z});
  if (!(edge > 0)) throw InputError("volume packing: the region of material " + std::to_string(label) + " is empty");

  std::vector<Vec3> seeds;
  std::vector<double> seed_h;
  Seeder sd{field, iso, p, seeds, seed_h};
  sd.visit(box.lo, edge, 0);

  // Seeds keep their clearance from the fixed boundary particles (radius 0:
  // never dropped) and from each other.
  std::vector<Vec3> all(fixed);
  std::vector<double> radius(fixed.size(), 0.0);
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    all.push_back(seeds[i]);
    radius.push_back(p.seed_clearance * seed_h[i]);
  }
  const std::vector<std::size_t> keep = thin_points(all, radius, {});
  debug("volume packing, material " + std::to_string(label) + ": " + std::to_string(seeds.size()) +
        " lattice points, " + std::to_string(keep.size() - fixed.size()) + " after thinning");

  VolumeConstraint vc(field, iso);
  EngineParams ep;
  ep.energy = p.energy;
  ep.tolerance = p.tolerance;
  ep.max_iters = p.max_iters;
  ep.population_interval = p.population_interval;
  ep.population_tolerance = p.population_tolerance;
  ep.population_control = p.population_control;
  ep.seed = p.seed;
  ep.progress = p.progress;
  ep.sizing_mode = true;
  ep.sizing = p.sizing;
  ep.spacing = p.sizing ? 0 : p.spacing;
  ep.fine_bins = true;
  ParticleEngine<VolumeConstraint> e(vc, ep);
  e.set_scale(1);

  std::size_t nfixed = 0;
  for (const Vec3& x : fixed) {
    VolumeConstraint::Point b;
    b.x = x;
    e.add(b, 0, true);
    ++nfixed;
  }
  std::vector<ParticleEngine<VolumeConstraint>::Candidate> cands;
  for (std::size_t k : keep) {
    if (k < fixed.size()) continue;
    ParticleEngine<VolumeConstraint>::Candidate c;
    c.x = all[k];
    cands.push_back(c);
  }
  std::vector<VolumeConstraint::Point> placed;
  std::vector<char> ok;
  e.place_many(cands, 1, {}, placed, ok);
  VolumePackResult r;
  for (std::size_t i = 0; i < placed.size(); ++i)
    if (ok[i]) {
      e.add(placed[i]);
      ++r.seeds;
    }
  r.fixed = nfixed;
  if (r.seeds == 0) {
    // A region thinner than its spacing (frog bones at 2 mm): no interior
    // particle fits; the tetrahedralisation meshes it from its boundary.
    warn("volume packing: material " + std::to_string(label) +
         ": no seed point lies inside (a region thinner than its spacing); no interior particles");
    r.converged = true;
    return r;
  }
  if (p.progress)
    info("volume packing, material " + std::to_string(label) + ": " + std::to_string(nfixed) + " fixed, " +
         std::to_string(r.seeds) + " seeds");
  const auto lr = e.relax("volume " + std::to_string(label), false);
  r.converged = lr.converged;
  r.iterations = lr.iterations;
  r.splits = lr.splits;
  r.deletions = lr.deletions;
  r.fixed = nfixed;
  for (const auto& q : e.particles()) {
    if (q.fixed) continue;
    r.points.push_back(q.p.x);
    r.spacing.push_back(q.spacing);
    r.labels.push_back(label);
  }
  r.stats = e.stats();
  return r;
}

VolumePackResult pack_materials(const MaterialSet& materials, int outside_label, const std::vector<Vec3>& vertices,
                                const std::vector<std::array<int, 3>>& triangles,
                                const std::vector<std::array<int, 2>>& triangle_labels, const VolumePackParams& p) {
  if (triangles.size() != triangle_labels.size())
    throw InputError("volume packing: " + std::to_string(triangles.size()) + " triangles but " +
                     std::to_string(triangle_labels.size()) + " label pairs; expected one pair per triangle");
  VolumePackResult all;
  all.converged = true;
  for (std::size_t m = 0; m < materials.size(); ++m) {
    const int label = materials.labels[m];
    if (label == outside_label) continue;
    std::set<int> used;
    for (std::size_t t = 0; t < triangles.size(); ++t)
      if (triangle_labels[t][0] == label || triangle_labels[t][1] == label)
        for (int v : triangles[t]) used.insert(v);
    if (used.empty()) {
      warn("volume packing: material " + std::to_string(label) + " has no interface triangles; not packed");
      continue;
    }
    std::vector<Vec3> fixed;
    fixed.reserve(used.size());
    for (int v : used) {
      if (v < 0 || std::size_t(v) >= vertices.size())
        throw InputError("volume packing: triangle vertex " + std::to_string(v) + " out of range [0, " +
                         std::to_string(vertices.size()) + ")");
      fixed.push_back(vertices[std::size_t(v)]);
    }
    const auto region = material_region_field(materials, m);
    VolumePackResult r = pack_volume(*region, 0.0, fixed, p, label);
    all.points.insert(all.points.end(), r.points.begin(), r.points.end());
    all.spacing.insert(all.spacing.end(), r.spacing.begin(), r.spacing.end());
    all.labels.insert(all.labels.end(), r.labels.begin(), r.labels.end());
    all.fixed += r.fixed;
    all.seeds += r.seeds;
    all.converged = all.converged && r.converged;
    all.iterations += r.iterations;
    all.splits += r.splits;
    all.deletions += r.deletions;
    add_stats(all.stats, r.stats);
  }
  return all;
}

}  // namespace pm
