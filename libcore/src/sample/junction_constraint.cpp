#include "pm/sample/junction_constraint.h"

#include <cmath>

#include "engine_impl.h"

namespace pm {

JunctionConstraint::JunctionConstraint(const MaterialSet& m, const Box& domain, double tolerance)
    : m_(m), domain_(domain), tol_(tolerance), bounds_(material_bounds(m)) {}

std::int32_t JunctionConstraint::cell_index(const JunctionCell& c) {
  auto it = ids_.find(c);
  if (it != ids_.end()) return it->second;
  const std::int32_t id = std::int32_t(cells_.size());
  cells_.push_back(c);
  ids_.emplace(c, id);
  return id;
}

void JunctionConstraint::finish_cells() {
  const std::size_t nc = cells_.size();
  vis_.assign(nc * nc, 0);
  for (std::size_t a = 0; a < nc; ++a)
    for (std::size_t b = 0; b < nc; ++b)
      if (a != b && cells_[b].count > cells_[a].count && cells_[b].contains_all(cells_[a])) vis_[a * nc + b] = 1;
}

bool JunctionConstraint::place(const Vec3& x, const Point& like, int steps, double max_step, Point& out,
                               Probe& pr) const {
  CellProjectParams pp;
  pp.max_steps = steps;
  pp.tolerance = tol_;
  pp.max_step = max_step;
  pp.bounds = &bounds_;
  const CellProjection r = project_to_cell(m_, cells_[std::size_t(like.s.cell)], x, pp);
  pr.evaluations += r.evaluations;
  if (!is_finite(r.x)) return pr.fail(ProjectFailure::non_finite);
  if (!r.converged) return pr.fail(ProjectFailure::no_convergence);
  if (!r.dominant) return pr.fail(ProjectFailure::not_dominant);
  if (!domain_.contains(r.x)) return pr.fail(ProjectFailure::left_domain);
  out.x = r.x;
  out.n = r.frame;
  out.s.cell = like.s.cell;
  out.s.residual = r.residual;
  return true;
}

Vec3 JunctionConstraint::tangent(const Point& p, const Vec3& v) const {
  switch (cell(p).count) {
    case 2: return v - p.n * dot(p.n, v);
    case 3: return p.n * dot(p.n, v);
    default: return Vec3{};
  }
}

Vec3 JunctionConstraint::split_offset(const Point& p, double u, double dist) const {
  if (cell(p).count == 3) return p.n * (u < 0.5 ? dist : -dist);
  return tangent_offset(p.n, 2 * engine_constants::kPi * u, dist);
}

int JunctionConstraint::children(const Point& p, double theta, double dist, Vec3* out) const {
  switch (cell(p).count) {
    case 2: return quad_children(p.n, theta, dist, out);
    case 3:
      out[0] = p.n * dist;
      out[1] = p.n * -dist;
      return 2;
    default: out[0] = Vec3{}; return 1;
  }
}

template class ParticleEngine<JunctionConstraint>;

}  // namespace pm
