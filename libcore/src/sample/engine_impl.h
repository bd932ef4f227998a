#pragma once
// Template code of pm::ParticleEngine<C> (pm/sample/engine.h). Included only
// by the .cpp files that instantiate the engine for a constraint.
//
// Binning invariant (why 3x3x3 bins are enough and why colours make it
// race-free). Bins are rebuilt from the current positions at the start of a
// sweep (or with the neighbour lists). During a sweep each particle moves at
// most once, by at most its local spacing d_i <= D (longer trials are
// rejected), so any particle is within D of where it was binned. A particle
// evaluates trial positions within d_i <= D of its binned position; a pair
// interacts only when closer than 1/α_ij <= R (α is bounded from below).
// Hence interacting pairs were binned closer than R + 2D, and with bins of
// width W >= R + 2D every partner sits in the 3x3x3 block around i's bin.
// Colours: bin (bx,by,bz) has colour (bx%2) + 2(by%2) + 4(bz%2). A particle
// writes only itself and reads only the 3x3x3 block around its bin; two bins
// of one colour differ by >= 2 along some axis, so neither lies in the
// other's block: bins of one colour run concurrently without races and the
// outcome does not depend on the schedule. Colours run in a fixed order,
// particles within a bin in a fixed order: bit-identical for any thread
// count.
#include <array>
#include <atomic>
#include <queue>
#include <utility>

#include "pm/sample/engine.h"

namespace pm {

template <class C>
ParticleEngine<C>::ParticleEngine(const C& c, const EngineParams& p) : c_(c), p_(p) {
  beta_ = engine_beta();
  double d = 0;
  e_beta_ = particle_pair_energy(p_.energy, beta_, d);
  need_curvature_ = !p_.sizing_mode && p_.density > 0;
  typed_ = p_.types > 1;
  type_max_ = 1;
  for (int a = 0; a < p_.types; ++a)
    for (int b = 0; b < p_.types; ++b) type_max_ = std::max(type_max_, p_.type_scale[a][b]);
  set_scale(1.0);
}

template <class C>
void ParticleEngine<C>::set_scale(double k) {
  using namespace engine_constants;
  scale_ = k;
  s_ = p_.spacing * k;
  k_curv_ = p_.density * p_.spacing / (2 * kPi);
  alpha_cap_ = p_.alpha_cap * beta_ / s_;
  lists_valid_ = false;
}

template <class C>
typename ParticleEngine<C>::Particle ParticleEngine<C>::make(const Point& q, double attr, std::uint64_t id,
                                                             std::uint8_t type) const {
  using namespace engine_constants;
  Particle r;
  r.p = q;
  r.attr = attr;
  r.type = type;
  r.spacing = local_spacing(attr, type);
  r.lambda = std::min(kLambda0, kLambdaMaxPerSpacing2 * r.spacing * r.spacing);
  r.id = id;
  return r;
}

template <class C>
std::size_t ParticleEngine<C>::add(const Point& q, std::uint8_t type, bool fixed) {
  double a = 0;
  attribute(q, a);
  parts_.push_back(make(q, a, next_id_++, type));
  parts_.back().fixed = fixed;
  return parts_.size() - 1;
}

template <class C>
std::size_t ParticleEngine<C>::active_count() const {
  std::size_t n = 0;
  for (const Particle& q : parts_) n += q.fixed ? 0 : 1;
  return n;
}

template <class C>
void ParticleEngine<C>::merge(const EngineStats& l) {
  add_update_counters(st_, l);
}

template <class C>
void ParticleEngine<C>::place_many(const std::vector<Candidate>& cands, int steps,
                                   const std::vector<double>& max_step, std::vector<Point>& placed,
                                   std::vector<char>& ok, std::vector<char>* outside) {
  const std::size_t n = cands.size();
  placed.assign(n, Point{});
  ok.assign(n, 0);
  std::vector<ProjectFailure> why(n, ProjectFailure::none);
  if (outside) outside->assign(n, 0);
  std::atomic<std::uint64_t> evals{0};
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, n, 16), [&](const tbb::blocked_range<std::size_t>& r) {
    std::uint64_t count = 0;
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      Probe pr;
      const double ms = max_step.empty() ? 0.0 : max_step[i];
      if (c_.place(cands[i].x, cands[i].like, steps, ms, placed[i], pr)) {
        double a = 0;
        if (attribute(placed[i], a)) {
          ok[i] = 1;
        } else {
          why[i] = ProjectFailure::outside_sizing;
          if (outside) (*outside)[i] = 1;
        }
      } else {
        why[i] = pr.why == ProjectFailure::none ? ProjectFailure::no_convergence : pr.why;
      }
      count += pr.evaluations;
    }
    evals += count;
  });
  st_.field_evaluations += evals.load();
  for (std::size_t i = 0; i < n; ++i)
    if (!ok[i]) {
      ++st_.place_failures;
      ++st_.failures_by_reason[int(why[i])];
    }
}

// --- energy ---------------------------------------------------------------

template <class C>
double ParticleEngine<C>::energy_at(const Vec3& x, const Vec3& n, double a, std::uint8_t t,
                                    const std::vector<Cand>& cs, Vec3* v, int* nbrs) const {
  using namespace engine_constants;
  double e = 0;
  Vec3 force;
  int count = 0;
  // Sizing mode: β/(k min(h_i, h_j)) = max(β/(k h_i), β/(k h_j)) exactly
  // (rounding is monotone), so each side's part is divided out once.
  const bool sizing = p_.sizing_mode;
  const double part = sizing ? beta_ / (scale_ * a) : 0.0;
  // Two passes per chunk of candidates: the first finds, without a branch,
  // those within interaction range (about half of them, in no predictable
  // order: a branch there mispredicts half the time), the second sums their
  // energies in the candidates' order, so the sums are the same bit for bit
  // (the pair terms themselves four at a time, particle_pair_terms).
  constexpr std::size_t kChunk = 32;
  std::uint8_t sel[kChunk];
  double sel_al[kChunk], sel_d2[kChunk], sel_w[kChunk], sel_e[kChunk], sel_f[kChunk];
  for (std::size_t base = 0; base < cs.size(); base += kChunk) {
    const std::size_t m = std::min(kChunk, cs.size() - base);
    const Cand* cb = cs.data() + base;
    std::size_t k = 0;
    for (std::size_t j = 0; j < m; ++j) {
      const Cand& c = cb[j];
      const double d2 = norm2(x - c.x);
      double al;
      if (sizing) {
        al = std::max(std::max(part, c.a), alpha_floor_);
        if (typed_) al /= p_.type_scale[t][c.type];
      } else {
        al = alpha(a, c.a, t, c.type);
      }
      sel[k] = std::uint8_t(j);
      sel_al[k] = al;
      sel_d2[k] = d2;
      k += al * al * d2 < 1.0;
    }
    count += int(k);
    for (std::size_t s = 0; s < k; ++s) {
      const Cand& c = cb[sel[s]];
      sel_w[s] = c.weighted ? normal_weight(dot(n, c.n)) : 1.0;
    }
    particle_pair_terms(p_.energy, k, sel_d2, sel_al, sel_w, sel_e, v ? sel_f : nullptr);
    for (std::size_t s = 0; s < k; ++s) {
      if (sel_w[s] == 0) continue;
      e += sel_e[s];
      if (v) force -= (x - cb[sel[s]].x) * sel_f[s];
    }
  }
  if (v) *v = force;
  if (nbrs) *nbrs = count;
  return e;
}

// Gathers select their candidates a chunk at a time without a branch (about
// half of those scanned are out of reach, in no predictable order), then
// copy them in scan order: the same candidates in the same order as a test
// per candidate.
constexpr std::uint32_t kGatherChunk = 32;

template <class C>
template <class Id>
void ParticleEngine<C>::take_in_reach(std::size_t count, Id id, const Vec3& x, double r2, std::size_t self,
                                      const Particle& P, std::vector<Cand>& out) const {
  for (std::size_t j0 = 0; j0 < count; j0 += kGatherChunk) {
    const std::size_t end = std::min<std::size_t>(count, j0 + kGatherChunk);
    std::uint32_t sel[kGatherChunk];
    std::uint32_t n = 0;
    for (std::size_t j = j0; j < end; ++j) {
      const std::uint32_t q = id(j);
      sel[n] = q;
      n += (q != self) & (norm2(pos_[q] - x) < r2);
    }
    for (std::uint32_t s = 0; s < n; ++s)
      if (kCached || sees_index(P, sel[s])) push_neighbour(out, P, sel[s]);
  }
}

// Candidates within `reach` of x, excluding self and particles self does
// not see: from the fine grid when it is in use and its search stays inside
// the 3x3x3 block of bins (see build_fine), else from that block, where a
// neighbour bin is skipped when x lies farther than reach + d_max from it
// along an axis (its particles were binned inside it and moved at most d_max
// since).
template <class C>
void ParticleEngine<C>::gather(const Vec3& x, double reach, std::size_t self, std::size_t cell,
                               std::vector<Cand>& out) const {
  out.clear();
  const double r2 = reach * reach;
  if (fine_w_ > 0) {
    const double need = reach + cell_moved_[cell];
    if (need + fine_.width() < bins_.width()) {  // the rebuilt grid may be wider than fine_w_
      const Particle& P0 = parts_[self];
      fine_.visit_ball_ranges(x, need, [&](const std::uint32_t* b, const std::uint32_t* e) {
        take_in_reach(std::size_t(e - b), [b](std::size_t j) { return b[j]; }, x, r2, self, P0, out);
      });
      return;
    }
  }
  const std::int32_t* nb = bins_.block(cell);
  // A candidate within reach of x lies within reach + its move since the
  // binning of where it was binned; moves are bounded per bin (bin_moved_).
  double moved = 0;
  for (int k = 0; k < 27; ++k)
    if (nb[k] >= 0) moved = std::max(moved, bin_moved_[std::size_t(nb[k])]);
  const double pad = reach + moved;
  int m[3];
  bins_.axis_masks(cell, x, pad, m);
  const Particle& P = parts_[self];
  // Ranges that continue the previous one (sub-cell rows and bins that are
  // adjacent in memory) are scanned as one run: the same indices in the
  // same order, in fewer and longer scans.
  std::uint32_t run_b = 0, run_e = 0;
  auto scan_run = [&] {
    if (run_b < run_e)
      take_in_reach(run_e - run_b, [b = run_b](std::size_t j) { return std::uint32_t(b + j); }, x, r2, self, P, out);
  };
  for (int k = 0; k < 27; ++k) {
    if (nb[k] < 0) continue;
    if (!((m[0] >> (k % 3)) & 1) || !((m[1] >> ((k / 3) % 3)) & 1) || !((m[2] >> (k / 9)) & 1)) continue;
    bins_.visit_box(std::size_t(nb[k]), x, pad, [&](std::uint32_t b, std::uint32_t e) {
      if (b != run_e) {
        scan_run();
        run_b = b;
      }
      run_e = e;
    });
  }
  scan_run();
}

template <class C>
void ParticleEngine<C>::gather_list(const Vec3& x, double reach, std::size_t self, std::vector<Cand>& out) const {
  out.clear();
  const double r2 = reach * reach;
  const std::uint32_t* list = nbr_.data() + nbr_start_[self];
  take_in_reach(nbr_start_[self + 1] - nbr_start_[self], [list](std::size_t j) { return list[j]; }, x, r2, self,
                parts_[self], out);
}

// --- the moves (SPEC §3, adaptive step size) --------------------------------

template <class C>
void ParticleEngine<C>::update(std::size_t i, std::size_t cell, std::vector<Cand>& buf, EngineStats& ls) {
  using namespace engine_constants;
  Particle& P = parts_[i];
  ++ls.updates;
  // Trial positions lie within s_i of x_i and may not grow the local
  // spacing beyond kSpacingSlack s_i, which bounds their interaction radius.
  const double spacing_cap = varying() ? kSpacingSlack * P.spacing : P.spacing;
  // The first gather covers the current position and trial positions
  // within `margin` of it whose spacing grew by at most kFirstGatherGrowth;
  // a trial that needs more (its distance plus its own interaction radius)
  // gathers again with the full reach, which covers every allowed trial.
  // Either way every particle within interaction range of the evaluated
  // point is in `buf`.
  const double margin = kGatherMargin * P.spacing;
  const double full_reach = radius_bound(spacing_cap) + P.spacing;
  double reach = std::min(full_reach, radius_bound((varying() ? kFirstGatherGrowth : 1.0) * P.spacing) + margin);
  if (use_lists_)
    gather_list(P.p.x, reach, i, buf);
  else
    gather(P.p.x, reach, i, cell, buf);
  Vec3 v;
  const double e0 = energy_at(P.p.x, P.p.n, P.attr, P.type, buf, &v, nullptr);
  P.energy = e0;
  P.delta = 0;
  P.moved = 0;
  const Vec3 vt = c_.tangent(P.p, v);
  if (!(norm2(vt) > 0)) return;
  // The energy's slope along the move: v is the force -∇e, so e(λ) starts
  // as e_0 - λ v·v_t. A slope that is not positive leaves the factor rule.
  const double slope = dot(v, vt);
  const bool quadratic = p_.step_control == StepControl::quadratic && slope > 0;
  const double lambda_max = kLambdaMaxPerSpacing2 * P.spacing * P.spacing;
  double lambda = std::min(P.lambda, lambda_max);
  const double step_cap2 = P.spacing * P.spacing;
  Probe pr;
  bool only_failures = true;  // every trial so far failed in the constraint
  ProjectFailure last = ProjectFailure::none;
  for (bool first = true;; first = false) {
    ++ls.trials;
    Point q;
    pr.why = ProjectFailure::none;
    bool ok = c_.move(P.p, vt * lambda, p_.reproject_steps, P.spacing, q, pr);
    if (!ok) {
      ++ls.trial_failures;
      last = pr.why == ProjectFailure::none ? ProjectFailure::no_convergence : pr.why;
      ++ls.failures_by_reason[int(last)];
    } else {
      only_failures = false;
    }
    double attr = 0;
    ok = ok && norm2(q.x - P.p.x) <= step_cap2 && attribute(q, attr) &&
         (!varying() || local_spacing(attr, P.type) <= spacing_cap);
    if (ok && reach < full_reach &&
        norm(q.x - P.p.x) + radius_bound(local_spacing(attr, P.type)) > reach) {
      ++ls.regathers;
      reach = full_reach;
      if (use_lists_)
        gather_list(P.p.x, reach, i, buf);
      else
        gather(P.p.x, reach, i, cell, buf);
    }
    double next = lambda / p_.step_factor;  // the step after a rejection
    if (ok) {
      const double e1 = energy_at(q.x, q.n, attr, P.type, buf, nullptr, nullptr);
      if (e1 <= e0) {
        P.moved = std::sqrt(norm2(q.x - P.p.x)) / P.spacing;
        P.p = q;
        pos_[i] = q.x;
        P.attr = attr;
        P.spacing = local_spacing(attr, P.type);
        P.energy = e1;
        P.delta = e1 - e0;
        cache(i);
        if (quadratic)
          P.lambda = std::min(
              quadratic_step(lambda, slope, e1 - e0, lambda / p_.step_factor, lambda * p_.step_factor), lambda_max);
        else
          P.lambda = first ? std::min(lambda * p_.step_factor, lambda_max) : lambda;
        ls.field_evaluations += pr.evaluations;
        return;
      }
      if (quadratic) next = quadratic_step(lambda, slope, e1 - e0, lambda / p_.step_factor, lambda / 2);
    }
    ++ls.rejected;
    lambda = next;
    if (lambda <= kLambdaMin) {
      P.lambda = kLambdaMin;
      ls.field_evaluations += pr.evaluations;
      if (only_failures) {  // the constraint cannot project this particle: it stays put
        ++ls.stuck;
        if (P.id < ls.first_stuck_id) {
          ls.first_stuck_id = P.id;
          ls.first_failure = "particle " + std::to_string(P.id) + " at " + engine_fmt(P.p.x) + ": " +
                             project_failure_name(last);
        }
      }
      return;
    }
  }
}

// --- bins and lists ---------------------------------------------------------

constexpr std::size_t kRebinChunk = 4096;

template <class C>
void ParticleEngine<C>::rebin(bool for_lists) {
  using namespace engine_constants;
  const std::size_t n = parts_.size();
  // The elementwise passes over the particles run in parallel (a rebin comes
  // before every sweep while particles move fast, and was a serial 8% of the
  // brain's particle stage); maxima do not depend on the order.
  const std::size_t chunks = (n + kRebinChunk - 1) / kRebinChunk;
  std::vector<double> cmax(2 * chunks, 0.0);
  auto chunked = [&](auto&& f) {
    pm::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
      for (std::size_t i = c * kRebinChunk, e = std::min(n, i + kRebinChunk); i < e; ++i) f(c, i);
    });
  };
  chunked([&](std::size_t c, std::size_t i) {
    cmax[2 * c] = std::max(cmax[2 * c], parts_[i].spacing);
    if (p_.sizing_mode) cmax[2 * c + 1] = std::max(cmax[2 * c + 1], scale_ * parts_[i].attr);
  });
  double dmax = 0, hmax = 0;
  for (std::size_t c = 0; c < chunks; ++c) {
    dmax = std::max(dmax, cmax[2 * c]);
    hmax = std::max(hmax, cmax[2 * c + 1]);
  }
  if (!p_.sizing_mode) {
    r_max_ = s_ / beta_;  // α_ij >= β/s
  } else {
    r_max_ = kSizingSlack * hmax / beta_;
    alpha_floor_ = 1.0 / r_max_;
    std::fill(cmax.begin(), cmax.end(), 0.0);
    chunked([&](std::size_t c, std::size_t i) {
      Particle& q = parts_[i];
      q.spacing = local_spacing(q.attr, q.type);
      cmax[2 * c] = std::max(cmax[2 * c], q.spacing);
    });
    dmax = 0;
    for (std::size_t c = 0; c < chunks; ++c) dmax = std::max(dmax, cmax[2 * c]);
  }
  d_max_ = dmax;
  lists_valid_ = false;
  fine_w_ = 0;  // the fine grid indexes the old order
  const double w = r_max_ * type_max_ + (for_lists ? kSpacingSlack + 2 * kListSkin : 2.0) * d_max_;
  pos_.resize(n);
  active_.resize(n);
  chunked([&](std::size_t, std::size_t i) {
    pos_[i] = parts_[i].p.x;
    active_[i] = parts_[i].fixed ? 0 : 1;
  });
  // Engines with the fine grid gather from it: their bins need no sub-cells.
  bins_.build(pos_, w, active_, p_.fine_bins ? 1 : p_.sub_bins);
  const std::vector<std::uint32_t>& order = bins_.order();
  scratch_.resize(n);
  chunked([&](std::size_t, std::size_t i) { scratch_[i] = parts_[order[i]]; });
  parts_.swap(scratch_);
  binned_.resize(n);
  bin_moved_.assign(bins_.cells(), 0.0);
  if constexpr (kCached || kKeyed) cands_.resize(n);
  chunked([&](std::size_t, std::size_t i) {
    pos_[i] = binned_[i] = parts_[i].p.x;
    cache(i);
  });
  if (p_.fine_bins && !for_lists) build_fine();
}

// The fine grid (EngineParams::fine_bins): a dense grid of cells about half
// the median gather radius wide, rebuilt before every colour of a sweep, so
// a graded packing's small particles scan a ball of their own radius instead
// of 27 bins sized for the largest. Within a colour only the particles of
// the gathering particle's own bin have moved since the rebuild (bins of one
// colour never interact), at most cell_moved_[bin] each: the ball grows by
// that much. The search stays within reach + moved + one fine cell of x
// along every axis; below the bin width it never meets a bin of the same
// colour (one bin away at least), whose particles may be moving. Which grid
// a particle uses and the candidates' order depend only on the state: runs
// stay deterministic for any thread count.
constexpr double kFineQuantile = 0.5;
constexpr double kFinePerRadius = 0.5;    // fine cell width / the median gather radius
constexpr std::size_t kFineCellsPerParticle = 4;

template <class C>
void ParticleEngine<C>::build_fine() {
  using namespace engine_constants;
  const std::size_t n = parts_.size();
  fine_w_ = 0;
  cell_moved_.assign(bins_.cells(), 0.0);
  std::vector<double> need;
  need.reserve(n);
  for (const Particle& P : parts_) {
    if (P.fixed) continue;
    const double cap = varying() ? kSpacingSlack * P.spacing : P.spacing;
    need.push_back(radius_bound(cap) + kGatherMargin * P.spacing);
  }
  if (need.empty()) return;
  const std::size_t at = std::size_t(double(need.size()) * kFineQuantile);
  std::nth_element(need.begin(), need.begin() + std::ptrdiff_t(at), need.end());
  const double wf = kFinePerRadius * need[at];
  if (!(2 * wf < bins_.width())) return;  // no gain over the bins
  fine_.build(pos_, wf, kFineCellsPerParticle * n + 4096);
  fine_w_ = fine_.width();
}

// Cached neighbour lists (SPEC §3.7), built right after rebin(true):
// particle i lists every j within L_i + k_j of it it can see, L_i =
// radius_bound(t_i t_i s_i) + t_i s_i + k_i, where t_i = kSpacingSlack where
// the spacing varies (its spacing may grow that much before a rebuild, and a
// move's cap by that much again), else 1, and k = kListSkin × spacing is the
// drift allowed before a rebuild. Lists are rebuilt when any particle drifted
// farther than its k_i or its spacing outgrew t_i's assumption; then every
// particle within interaction range of any trial position is still listed.
// L_i <= the bin width, so the bin colouring still keeps parallel updates
// apart. Fixed particles get no list (they are never updated).
template <class C>
void ParticleEngine<C>::build_lists() {
  using namespace engine_constants;
  const std::size_t n = parts_.size();
  const double step_factor = varying() ? kSpacingSlack : 1.0;
  list_x_.resize(n);
  list_s_.resize(n);
  nbr_start_.assign(n + 1, 0u);
  // Two passes over the 3x3x3 blocks (count, then fill at the prefix sums):
  // deterministic for any schedule, one flat array.
  auto scan = [&](std::size_t c, bool fill) {
    const std::int32_t* nb = bins_.block(c);
    for (std::uint32_t i = bins_.begin(c); i < bins_.end(c); ++i) {
      const Particle& P = parts_[i];
      std::uint32_t count = 0, at = fill ? nbr_start_[i] : 0;
      if (!P.fixed) {
        const double reach =
            radius_bound(step_factor * step_factor * P.spacing) + step_factor * P.spacing + kListSkin * P.spacing;
        // Skip the neighbour bins farther than the longest list reach along an axis.
        int m[3];
        const double pad = reach + kListSkin * d_max_;
        bins_.axis_masks(c, P.p.x, pad, m);
        for (int k = 0; k < 27; ++k) {
          if (nb[k] < 0) continue;
          if (!((m[0] >> (k % 3)) & 1) || !((m[1] >> ((k / 3) % 3)) & 1) || !((m[2] >> (k / 9)) & 1)) continue;
          bins_.visit_box(std::size_t(nb[k]), P.p.x, pad, [&](std::uint32_t b, std::uint32_t e) {
            for (std::uint32_t q = b; q < e; ++q) {
              const double rq = reach + kListSkin * parts_[q].spacing;
              if (q == i || norm2(pos_[q] - P.p.x) >= rq * rq || !sees(P, parts_[q])) continue;
              if (fill)
                nbr_[at++] = q;
              else
                ++count;
            }
          });
        }
      }
      if (!fill) nbr_start_[i + 1] = count;
    }
  };
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, bins_.cells(), 4),
                   [&](const tbb::blocked_range<std::size_t>& r) {
                     for (std::size_t c = r.begin(); c != r.end(); ++c) scan(c, false);
                   });
  for (std::size_t i = 0; i < n; ++i) nbr_start_[i + 1] += nbr_start_[i];
  nbr_.resize(nbr_start_[n]);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, bins_.cells(), 4),
                   [&](const tbb::blocked_range<std::size_t>& r) {
                     for (std::size_t c = r.begin(); c != r.end(); ++c) scan(c, true);
                   });
  for (std::size_t i = 0; i < n; ++i) {
    list_x_[i] = parts_[i].p.x;
    list_s_[i] = parts_[i].spacing;
  }
  lists_valid_ = true;
  ++st_.list_builds;
}

template <class C>
bool ParticleEngine<C>::lists_stale() const {
  using namespace engine_constants;
  if (!lists_valid_ || list_x_.size() != parts_.size()) return true;
  const double step_factor = varying() ? kSpacingSlack : 1.0;
  for (std::size_t i = 0; i < parts_.size(); ++i) {
    const double k = kListSkin * list_s_[i];
    if (norm2(pos_[i] - list_x_[i]) > k * k) return true;
    // The trial step is capped by the current spacing: it may not outgrow
    // the step the list allowed for (uniform spacing never changes).
    if (varying() && parts_[i].spacing > step_factor * list_s_[i]) return true;
  }
  return false;
}

// --- sweeps -------------------------------------------------------------------

// One Gauss-Seidel sweep over the active particles. Returns the decrease of
// the system energy, 2 Σ_i (E_old - E_new) over the accepted moves (E_ij =
// E_ji; pairs with fixed particles count once, so with fixed particles this
// is an upper bound, fine as a convergence measure); `energy` receives Σ E_i
// of the active particles as seen by the sweep.
template <class C>
double ParticleEngine<C>::sweep(double& energy) {
  using namespace engine_constants;
  for (EngineStats& l : tls_stats_) l = EngineStats{};
  auto run_cells = [&](std::uint32_t b, std::uint32_t e) {
    std::vector<Cand>& buf = tls_.local();
    EngineStats& ls = tls_stats_.local();
    for (std::uint32_t k = b; k != e; ++k) {
      const std::uint32_t c = bins_.colour_cell(k);
      if (fine_w_ > 0) cell_moved_[c] = 0;  // the fine grid was rebuilt before this colour
      for (std::uint32_t i = bins_.begin(c); i < bins_.end(c); ++i) {
        Particle& P = parts_[i];
        if (P.fixed) continue;
        if (p_.settled_move > 0 && P.quiet > 0 && (iteration_ + P.id) % std::uint64_t(p_.settled_recheck) != 0) {
          ++ls.settled_skips;
          P.delta = 0;
          P.moved = 0;
          continue;
        }
        const Vec3 before = pos_[i];
        update(i, c, buf, ls);
        if (fine_w_ > 0) cell_moved_[c] = std::max(cell_moved_[c], norm(pos_[i] - before));
        bin_moved_[c] = std::max(bin_moved_[c], norm(pos_[i] - binned_[i]));
      }
    }
  };
  // Small systems run on the calling thread: eight parallel_for rounds per
  // sweep cost more than they save below a few thousand particles (same
  // result either way, see the colouring argument above).
  const bool serial = parts_.size() < kSerialBelow;
  for (int colour = 0; colour < kColours; ++colour) {
    const std::uint32_t b = bins_.colour_begin(colour), e = bins_.colour_end(colour);
    if (b == e) continue;
    if (fine_w_ > 0) fine_.build(pos_, fine_w_, kFineCellsPerParticle * pos_.size() + 4096);  // after the previous colours
    if (serial) {
      run_cells(b, e);
      continue;
    }
    pm::parallel_for(tbb::blocked_range<std::uint32_t>(b, e, 1), [&](const tbb::blocked_range<std::uint32_t>& r) {
      run_cells(r.begin(), r.end());
    });
  }
  const bool had_stuck = st_.stuck > 0;
  EngineStats first;
  for (const EngineStats& l : tls_stats_) {
    merge(l);
    if (l.first_stuck_id < first.first_stuck_id) first = l;
  }
  if (!had_stuck && st_.stuck > 0) {  // the smallest id of the first sweep with any: schedule-independent
    st_.first_stuck_id = first.first_stuck_id;
    st_.first_failure = first.first_failure;
  }
  double de = 0;
  energy = 0;
  max_move_ = 0;
  for (const Particle& q : parts_) {
    if (q.fixed) continue;
    de += q.delta;
    energy += q.energy;
    max_move_ = std::max(max_move_, q.moved);
  }
  if (p_.settled_move > 0) settle_marks();
  return -2 * de;
}

// A particle is settled when it moved less than settled_move spacings in
// this sweep and no particle that moved more lies within that particle's
// reach (the interaction radius its spacing may grow to, plus one spacing
// of trial): the movers wake their neighbourhoods, everyone else counts one
// more quiet sweep. The bins are those of the sweep or of the lists (their
// particles drifted at most d_max or the list skin, both inside the 3x3x3
// block). Marks are set, not counted: the result does not depend on order.
template <class C>
void ParticleEngine<C>::settle_marks() {
  using namespace engine_constants;
  const std::size_t n = parts_.size();
  std::size_t movers = 0;
  for (const Particle& q : parts_) movers += !q.fixed && q.moved >= p_.settled_move;
  if (double(movers) > kWakeScanShare * double(n)) {
    for (Particle& q : parts_) q.quiet = 0;
    return;
  }
  awake_.assign(n, 0);
  const double slack = varying() ? kSpacingSlack : 1.0;
  for (std::size_t j = 0; j < n; ++j) {
    const Particle& P = parts_[j];
    if (P.fixed || P.moved < p_.settled_move) continue;
    awake_[j] = 1;
    for_each_near(pos_[j], radius_bound(slack * P.spacing) + P.spacing, [&](std::size_t q) { awake_[q] = 1; });
  }
  for (std::size_t i = 0; i < n; ++i) {
    Particle& q = parts_[i];
    q.quiet = awake_[i] || q.fixed ? 0 : std::uint16_t(std::min<int>(q.quiet + 1, 60000));
  }
}

template <class C>
double ParticleEngine<C>::measure() {
  rebin();
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, bins_.cells(), 1), [&](const tbb::blocked_range<std::size_t>& r) {
    std::vector<Cand>& buf = tls_.local();
    for (std::size_t c = r.begin(); c != r.end(); ++c)
      for (std::uint32_t i = bins_.begin(c); i < bins_.end(c); ++i) {
        Particle& P = parts_[i];
        if (P.fixed) continue;
        gather(P.p.x, radius_bound(P.spacing), i, c, buf);
        int nb = 0;
        P.energy = energy_at(P.p.x, P.p.n, P.attr, P.type, buf, nullptr, &nb);
        P.neighbours = nb;
      }
  });
  double e = 0;
  for (const Particle& q : parts_)
    if (!q.fixed) e += q.energy;
  return e;
}

template <class C>
std::size_t ParticleEngine<C>::retype() {
  using namespace engine_constants;
  rebin();
  std::atomic<std::size_t> flips{0};
  auto run_cells = [&](std::uint32_t b, std::uint32_t e) {
    std::vector<Cand>& buf = tls_.local();
    std::size_t local = 0;
    for (std::uint32_t k = b; k != e; ++k) {
      const std::uint32_t c = bins_.colour_cell(k);
      for (std::uint32_t i = bins_.begin(c); i < bins_.end(c); ++i) {
        Particle& P = parts_[i];
        if (P.fixed) continue;
        gather(P.p.x, radius_bound(P.spacing), i, c, buf);
        const std::uint8_t other = std::uint8_t(1 - P.type);
        const double e0 = energy_at(P.p.x, P.p.n, P.attr, P.type, buf, nullptr, nullptr);
        const double e1 = energy_at(P.p.x, P.p.n, P.attr, other, buf, nullptr, nullptr);
        // A margin keeps a particle between two equally good types from flipping back and forth.
        if (e1 < (1 - kRetypeMargin) * e0) {
          P.type = other;
          P.spacing = local_spacing(P.attr, P.type);
          cache(i);
          ++local;
        }
      }
    }
    flips += local;
  };
  for (int colour = 0; colour < kColours; ++colour) {
    const std::uint32_t b = bins_.colour_begin(colour), e = bins_.colour_end(colour);
    if (b == e) continue;
    pm::parallel_for(tbb::blocked_range<std::uint32_t>(b, e, 1), [&](const tbb::blocked_range<std::uint32_t>& r) {
      run_cells(r.begin(), r.end());
    });
  }
  return flips.load();
}

template <class C>
std::size_t ParticleEngine<C>::grow_types(bool force) {
  rebin();
  const std::size_t n = parts_.size();
  // Pair weights w_ij over the particles within reach, as CSR lists.
  std::vector<std::uint32_t> start(n + 1, 0), nbr;
  std::vector<double> weight;
  for (std::size_t i = 0; i < n; ++i) {
    const Particle& P = parts_[i];
    start[i] = std::uint32_t(nbr.size());
    if (P.fixed) continue;
    for_each_near(P.p.x, radius_bound(P.spacing), [&](std::size_t q) {
      if (q == i || !sees(P, parts_[q])) return;
      const Particle& o = parts_[q];
      const Cand c = cand_of(P, o);
      const double w = c.weighted ? normal_weight(dot(P.p.n, c.n)) : 1.0;
      const double r = norm(P.p.x - o.p.x);
      double de = 0;
      const double el = r * alpha(P.attr, o.attr, 0, 0) < 1
                            ? particle_pair_energy(p_.energy, r * alpha(P.attr, o.attr, 0, 0), de)
                            : 0.0;
      const double eu = r * alpha(P.attr, o.attr, 0, 1) < 1
                            ? particle_pair_energy(p_.energy, r * alpha(P.attr, o.attr, 0, 1), de)
                            : 0.0;
      if (w * (el - eu) <= 0) return;
      nbr.push_back(std::uint32_t(q));
      weight.push_back(w * (el - eu));
    });
  }
  start[n] = std::uint32_t(nbr.size());
  // pull[i][t]: weight towards typed neighbours of type t.
  std::vector<std::array<double, 2>> pull(n, {0.0, 0.0});
  std::vector<char> done(n, 0);
  std::vector<std::uint8_t> old(n);
  for (std::size_t i = 0; i < n; ++i) old[i] = parts_[i].type;
  using Item = std::pair<double, std::uint32_t>;  // (pull, -index order via comparator)
  auto later = [](const Item& a, const Item& b) { return a.first != b.first ? a.first < b.first : a.second > b.second; };
  std::priority_queue<Item, std::vector<Item>, decltype(later)> heap(later);
  auto settle = [&](std::size_t i, std::uint8_t t) {
    done[i] = 1;
    parts_[i].type = t;
    for (std::uint32_t k = start[i]; k < start[i + 1]; ++k) {
      const std::uint32_t q = nbr[k];
      if (done[q]) continue;
      pull[q][t] += weight[k];
      heap.push({pull[q][0] + pull[q][1], q});
    }
  };
  for (std::size_t i = 0; i < n; ++i)
    if (parts_[i].fixed) settle(i, parts_[i].type);
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (done[seed]) continue;
    settle(seed, old[seed]);
    while (!heap.empty()) {
      const std::uint32_t q = heap.top().second;
      heap.pop();
      if (done[q]) continue;
      settle(q, pull[q][0] > pull[q][1] ? std::uint8_t(1) : pull[q][1] > pull[q][0] ? std::uint8_t(0) : old[q]);
    }
  }
  // Keep the new colouring only when its frustration (the weight of like
  // pairs) is clearly lower: a packing already coloured as one grain gets the
  // same colouring back, or its phase inverse, and keeps its own.
  double cost_old = 0, cost_new = 0;
  for (std::size_t i = 0; i < n; ++i)
    for (std::uint32_t k = start[i]; k < start[i + 1]; ++k) {
      const std::uint32_t q = nbr[k];
      if (old[i] == old[q]) cost_old += weight[k];
      if (parts_[i].type == parts_[q].type) cost_new += weight[k];
    }
  if (!force && !(cost_new < (1 - engine_constants::kRetypeMargin) * cost_old)) {
    for (std::size_t i = 0; i < n; ++i) parts_[i].type = old[i];
    return 0;
  }
  std::size_t changed = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (parts_[i].type == old[i]) continue;
    ++changed;
    parts_[i].spacing = local_spacing(parts_[i].attr, parts_[i].type);
    cache(i);
  }
  return changed;
}

// --- population -----------------------------------------------------------------

template <class C>
bool ParticleEngine<C>::population_control(std::uint64_t tag, bool final_check, LevelResult& lr) {
  using namespace engine_constants;
  measure();
  const std::size_t n = parts_.size();
  std::vector<char> del(n, 0);
  std::vector<Candidate> kids;
  std::vector<double> steps;
  std::vector<std::uint64_t> parent;
  std::size_t ndel = 0, nactive = 0, certain = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Particle& q = parts_[i];
    if (q.fixed) continue;
    ++nactive;
    // Biased energy E_i (1 + u)/2, u uniform on [0, 1]: neighbours with
    // similar energies do not all split or die together.
    const double ideal = ideal_energy(q);
    const double biased = q.energy * (1 + counter_uniform(p_.seed, q.id, tag, kStreamPopulation)) / 2;
    const double delete_at = c_.delete_above(q.p) * ideal, split_at = c_.split_below(q.p) * ideal;
    certain += q.energy / 2 > delete_at || q.energy < split_at;  // whatever the draw
    if (biased > delete_at) {
      del[i] = 1;
      ++ndel;
    } else if (biased < split_at) {
      const double u = counter_uniform(p_.seed, q.id, tag, kStreamSplitDir);
      kids.push_back({q.p.x + c_.split_offset(q.p, u, kSplitOffset * q.spacing), q.p,
                      p_.alternate_types ? std::uint8_t(1 - q.type) : q.type});
      steps.push_back(q.spacing);
      parent.push_back(q.id);
    }
  }
  keep_anchor_covers(del, ndel);
  if (p_.keep_covered) keep_covered(del, ndel);
  if (final_check) {
    const double tol = p_.population_tolerance * double(nactive);
    if (double(ndel + kids.size()) <= tol) return false;
    const double net = std::fabs(double(kids.size()) - double(ndel));
    if (p_.population_balance && net <= tol && double(certain) <= tol) {
      balanced_ = true;
      return false;
    }
  }
  if (ndel == nactive && ndel) {  // never empty the system
    for (std::size_t i = 0; i < n; ++i)
      if (del[i]) {
        del[i] = 0;
        --ndel;
        break;
      }
  }
  std::vector<Point> placed;
  std::vector<char> ok;
  place_many(kids, kPlaceSteps, steps, placed, ok);
  scratch_.clear();
  for (std::size_t i = 0; i < n; ++i)
    if (!del[i]) scratch_.push_back(parts_[i]);
  std::size_t nsplit = 0;
  for (std::size_t k = 0; k < kids.size(); ++k) {
    if (!ok[k]) continue;
    double a = 0;
    attribute(placed[k], a);
    scratch_.push_back(make(placed[k], a, next_id_++, kids[k].type));
    ++nsplit;
  }
  parts_.swap(scratch_);
  lr.splits += nsplit;
  lr.deletions += ndel;
  return nsplit + ndel > 0;
}

// Fixed count: scale the spacing so that the mean particle energy approaches
// the mean ideal one.
template <class C>
bool ParticleEngine<C>::adapt_spacing() {
  using namespace engine_constants;
  const double e = measure();
  double ideal = 0;
  std::size_t n = 0;
  for (const Particle& q : parts_)
    if (!q.fixed) {
      ideal += ideal_energy(q);
      ++n;
    }
  const double mean = e / double(n);
  double factor = mean > 0 ? std::pow(ideal / double(n) / mean, kCountExponent) : kCountClamp;
  factor = std::clamp(factor, 1 / kCountClamp, kCountClamp);
  if (std::fabs(factor - 1) <= kCountSettled) return false;
  set_scale(scale_ * factor);
  refresh_spacings();
  return true;
}

template <class C>
void ParticleEngine<C>::split_all() {
  using namespace engine_constants;
  const std::size_t n = parts_.size();
  std::vector<Candidate> kids;
  std::vector<std::size_t> from;
  kids.reserve(4 * n);
  Vec3 off[8];
  for (std::size_t i = 0; i < n; ++i) {
    const Particle& q = parts_[i];
    const double th = 2 * kPi * counter_uniform(p_.seed, q.id, iteration_, kStreamQuad);
    const int k = c_.children(q.p, th, kQuadOffset * q.spacing, off);
    for (int c = 0; c < k; ++c) {
      kids.push_back({q.p.x + off[c], q.p, p_.alternate_types ? std::uint8_t(q.type ^ (c & 1)) : q.type});
      from.push_back(i);
    }
  }
  std::vector<Point> placed;
  std::vector<char> ok;
  place_many(kids, kPlaceSteps, {}, placed, ok);
  set_scale(scale_ / 2);
  scratch_.clear();
  std::size_t last = std::size_t(-1);
  for (std::size_t k = 0; k < kids.size(); ++k) {
    if (!ok[k]) continue;
    double a = 0;
    attribute(placed[k], a);
    const bool first = from[k] != last;
    last = from[k];
    scratch_.push_back(make(placed[k], a, first ? parts_[from[k]].id : next_id_++, kids[k].type));
  }
  if (!scratch_.empty())
    parts_.swap(scratch_);
  else
    refresh_spacings();
}

// Index of the particle nearest to anchor a among those within kHoleRadius ×
// its local spacing with a normal on the same side and not `dead`, or -1.
// Needs valid bins.
template <class C>
std::int64_t ParticleEngine<C>::anchor_cover(const Particle& a, const std::vector<char>* dead) const {
  using namespace engine_constants;
  const double R = kHoleRadius * local_spacing(a.attr, a.type);
  std::int64_t best = -1;
  double best_d2 = R * R;
  for_each_near(a.p.x, R, [&](std::size_t q) {
    const double d2 = norm2(pos_[q] - a.p.x);
    if (d2 >= best_d2 || (dead && (*dead)[q]) || dot(parts_[q].p.n, a.p.n) <= 0) return;
    best_d2 = d2;
    best = std::int64_t(q);
  });
  return best;
}

template <class C>
std::size_t ParticleEngine<C>::refill_holes() {
  using namespace engine_constants;
  if (anchors_.empty()) return 0;
  rebin();
  const std::size_t na = anchors_.size();
  std::vector<char> hole(na, 0);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, na, 256), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k) hole[k] = anchor_cover(anchors_[k], nullptr) < 0;
  });
  // Greedy in anchor order (deterministic): one new particle covers the
  // anchors near it; holes are few, so a linear scan of the added ones is fine.
  std::vector<std::size_t> added;
  for (std::size_t k = 0; k < na; ++k) {
    if (!hole[k]) continue;
    const Particle& a = anchors_[k];
    const double R = kHoleRadius * local_spacing(a.attr, a.type);
    bool near = false;
    for (std::size_t i : added)
      if (norm2(parts_[i].p.x - a.p.x) < R * R && dot(parts_[i].p.n, a.p.n) > 0) {
        near = true;
        break;
      }
    if (near) continue;
    added.push_back(parts_.size());
    parts_.push_back(make(a.p, a.attr, next_id_++, a.type));
  }
  return added.size();
}

template <class C>
void ParticleEngine<C>::keep_anchor_covers(std::vector<char>& del, std::size_t& ndel) const {
  if (!guard_anchors_ || anchors_.empty() || ndel == 0) return;
  const std::size_t na = anchors_.size();
  // Anchors that are covered now but would lose every cover (parallel, pure reads).
  std::vector<char> risk(na, 0);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, na, 256), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t k = r.begin(); k != r.end(); ++k)
      risk[k] = anchor_cover(anchors_[k], nullptr) >= 0 && anchor_cover(anchors_[k], &del) < 0;
  });
  // In anchor order, spare the nearest cover (which may cover later anchors too).
  for (std::size_t k = 0; k < na; ++k) {
    if (!risk[k] || anchor_cover(anchors_[k], &del) >= 0) continue;
    const std::int64_t q = anchor_cover(anchors_[k], nullptr);
    del[std::size_t(q)] = 0;
    --ndel;
  }
}

// Crowded neighbours all have high energies, so they can all be marked for
// deletion in the same round and leave a hole (a short junction curve then
// loses every particle). In bin order, a marked particle is only deleted when
// an active particle of its cell that stays lies within its interaction
// radius. Deterministic; needs the bins of measure().
template <class C>
void ParticleEngine<C>::keep_covered(std::vector<char>& del, std::size_t& ndel) const {
  for (std::size_t i = 0; i < parts_.size(); ++i) {
    if (!del[i]) continue;
    const Particle& P = parts_[i];
    bool covered = false;
    for_each_near(P.p.x, radius_bound(P.spacing), [&](std::size_t q) {
      if (covered || q == i || del[q] || parts_[q].fixed || !c_.same_cell(P.p, parts_[q].p)) return;
      const double al = pair_alpha(P, parts_[q]);
      covered = al * al * norm2(pos_[q] - P.p.x) < 1.0;
    });
    if (!covered) {
      del[i] = 0;
      --ndel;
    }
  }
}

// --- one level ---------------------------------------------------------------------

template <class C>
typename ParticleEngine<C>::LevelResult ParticleEngine<C>::relax(const std::string& label, bool fixed_count) {
  using namespace engine_constants;
  LevelResult lr;
  if (active_count() == 0) {
    lr.converged = true;
    return lr;
  }
  Progress progress(label, std::size_t(p_.max_iters));
  // Convergence: the exact decrease of the system energy in one sweep,
  // relative to the system energy (the sweep's sum, accurate enough as a
  // scale); not disturbed by the staleness of Gauss-Seidel energies.
  int since = 0, refills = 0;
  int interval = p_.first_population_interval > 0 ? std::min(p_.first_population_interval, p_.population_interval)
                                                  : p_.population_interval;
  for (Particle& q : parts_) q.quiet = 0;
  balanced_ = false;
  bool polishing = false;
  for (int it = 0; it < p_.max_iters; ++it) {
    Stopwatch sw;
    if (p_.alternate_types && iteration_ < std::uint64_t(std::max(0, p_.recolour_sweeps))) {
      grow_types(true);  // rebins (particles move in memory): lists are rebuilt
      if (use_lists_) {
        rebin(true);
        build_lists();
      }
    } else if (!use_lists_) {
      rebin();  // gather from the bins, rebuilt every sweep
    } else if (lists_stale()) {
      rebin(true);
      build_lists();
    }
    double e = 0;
    const double change = sweep(e);
    // Lists pay off once particles move slowly (a list then serves many
    // sweeps); while they still move fast, bins rebuilt every sweep are
    // cheaper than lists rebuilt every sweep.
    const bool slow = max_move_ < kListsBelowMove;
    if (slow != use_lists_) {
      use_lists_ = slow;
      lists_valid_ = false;
    }
    st_.seconds_relax += sw.seconds();
    ++iteration_;
    ++lr.iterations;
    ++since;
    const bool conv = change <= p_.tolerance * (polishing ? kBalancePolish : 1.0) * e;
    if (p_.progress) {
      char detail[96];
      std::snprintf(detail, sizeof detail, "%zu particles, dE %.3g%%", parts_.size(),
                    e > 0 ? 100 * change / e : 0.0);
      progress.update(std::size_t(it + 1), detail);
    }
    if (conv || since >= interval) {
      since = 0;
      interval = std::min(2 * interval, p_.population_interval);
      Stopwatch sp;
      bool changed = false;
      if (!polishing) {  // no population checks while polishing
        if (p_.alternate_types) {
          const std::size_t grown = grow_types(false);
          changed = retype() + grown > 0;
        }
        if (fixed_count)
          changed = adapt_spacing() || changed;
        else if (p_.population_control)
          changed = population_control(iteration_, conv, lr) || changed;
      }
      if (changed)
        for (Particle& q : parts_) q.quiet = 0;
      st_.seconds_population += sp.seconds();
      if (conv && !changed) {
        if (balanced_ && !polishing) {  // population_balance: relax on to kBalancePolish x tolerance
          polishing = true;
          continue;
        }
        if (guard_anchors_ && refills < kMaxRefills) {
          Stopwatch sr;
          const std::size_t added = refill_holes();
          st_.seconds_population += sr.seconds();
          if (added > 0) {
            ++refills;
            lr.refilled += added;
            debug("refilled " + std::to_string(added) + " hole(s) left by coarser levels");
            continue;
          }
        }
        lr.converged = true;
        return lr;
      }
    }
  }
  return lr;
}

}  // namespace pm
