#include "pm/sample/multiparticles.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <string>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/parallel.h"
#include "pm/volume/mcinit.h"

// Binning: the same invariant as particles.cpp. Bins are rebuilt before each
// sweep; a particle moves at most once per sweep and by at most its spacing
// h_i <= H (H = largest h at rebinning); pair radii are capped at H/β (α is
// floored at β/H). With bins of width H/β + 2H every partner of a particle
// lies in the 3x3x3 block around its bin, and bins of one colour
// (bx%2, by%2, bz%2) never read or write each other's particles, so they
// run in parallel with a result independent of the schedule.

namespace pm {
namespace {

constexpr double kPi = 3.14159265358979323846;
const double kBeta = 0.5 / std::cos(kPi / 6);
constexpr double kEpsR = 1e-7;
constexpr double kGamma = 0.156;
constexpr double kLambdaMin = 1e-14;
constexpr double kLambdaMaxPerH2 = 100.0;
constexpr int kReprojectSteps = 6;
constexpr int kColours = 8;

std::uint64_t mix64(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
double uniform01(std::uint64_t seed, std::uint64_t id, std::uint64_t iter, std::uint64_t stream) {
  std::uint64_t h = mix64(seed ^ 0x2545F4914F6CDD1Dull);
  h = mix64(h ^ id);
  h = mix64(h ^ (iter * 0xD1B54A32D192ED03ull));
  h = mix64(h ^ (stream * 0x8CB92BA72F3D8DD7ull));
  return double(h >> 11) * 0x1.0p-53;
}
enum Stream : std::uint64_t { kStreamPopulation = 11, kStreamSplitDir = 12 };

double normal_weight(double d) {
  if (d > kGamma) return 1.0;
  if (d <= 0) return 0.0;
  return std::cos(0.5 * kPi * (kGamma - d) / kGamma);
}

std::string fmt(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}
std::string fmt(const Vec3& v) { return "(" + fmt(v.x) + ", " + fmt(v.y) + ", " + fmt(v.z) + ")"; }

struct MP {
  Vec3 x;
  Vec3 frame;          // surface normal (a -> b) or curve tangent
  double h = 0;        // local spacing
  double lambda = 1;
  double energy = 0;
  double delta = 0;
  double resid = 0;
  std::uint64_t id = 0;
  std::int32_t cell = 0;
  std::int32_t level = 0;  // cell dimension order: 0 points, 1 curves, 2 surfaces
  bool fixed = false;
};

struct Cand {
  Vec3 x, n;
  double h;
  bool weighted;  // same surface cell: normal weighting applies
};

struct Candidate {  // a projected seed or split child
  Vec3 x;
  std::int32_t cell;
  std::size_t order;
};

class MultiEngine {
 public:
  MultiEngine(const MaterialSet& m, const SizingField* sizing, const MultiParticleParams& p)
      : m_(m), sizing_(sizing), p_(p) {
    domain_ = m.fields[0]->domain();
    resolution_ = m.fields[0]->resolution();
    for (const auto& f : m.fields) {
      const Box b = f->domain();
      for (int a = 0; a < 3; ++a) {
        domain_.lo[a] = std::max(domain_.lo[a], b.lo[a]);
        domain_.hi[a] = std::min(domain_.hi[a], b.hi[a]);
      }
      resolution_ = std::min(resolution_, f->resolution());
    }
    tol_ = p.projection_tolerance > 0 ? p.projection_tolerance : 1e-6 * resolution_;
  }

  const Box& domain() const { return domain_; }
  MultiParticleResult run(const std::vector<JunctionSeed>& seeds);

 private:
  bool spacing_at(const Vec3& x, double& h) const {
    if (!sizing_) {
      h = p_.spacing;
      return true;
    }
    return sizing_->sample(x, h) && h > 0;
  }
  double alpha(double hi, double hj) const { return std::max(kBeta / std::min(hi, hj), alpha_floor_); }

  // Re-project x onto cell c; on success fills x, frame, h, resid.
  bool place(const JunctionCell& c, Vec3& x, Vec3& frame, double& h, double& resid, int steps, double max_step,
             std::uint64_t& evals) const {
    CellProjectParams pp;
    pp.max_steps = steps;
    pp.tolerance = tol_;
    pp.max_step = max_step;
    const CellProjection pr = project_to_cell(m_, c, x, pp);
    evals += pr.evaluations;
    if (!pr.converged || !pr.dominant || !domain_.contains(pr.x)) return false;
    if (!spacing_at(pr.x, h)) return false;
    x = pr.x;
    frame = pr.frame;
    resid = pr.residual;
    return true;
  }

  double energy_at(const Vec3& x, const Vec3& n, double h, const std::vector<Cand>& cs, Vec3* v, int* nb) const {
    double e = 0;
    Vec3 force;
    int count = 0;
    for (const Cand& c : cs) {
      const Vec3 d = x - c.x;
      const double d2 = norm2(d);
      const double al = alpha(h, c.h);
      if (al * al * d2 >= 1.0) continue;
      ++count;
      const double w = c.weighted ? normal_weight(dot(n, c.n)) : 1.0;
      if (w == 0) continue;
      const double dist = std::sqrt(d2);
      double de = 0;
      e += w * particle_pair_energy(p_.energy, al * dist + kEpsR, de);
      if (v && dist > 0) force -= d * (w * de * al / dist);
    }
    if (v) *v = force;
    if (nb) *nb = count;
    return e;
  }

  bool visible(std::int32_t ci, const MP& o) const {
    return o.cell == ci || (o.fixed && vis_[std::size_t(ci) * cells_.size() + std::size_t(o.cell)]);
  }

  void gather(const MP& P, std::size_t self, std::size_t bin, double reach, std::vector<Cand>& out) const {
    out.clear();
    const double r2 = reach * reach;
    const bool surf = cells_[std::size_t(P.cell)].count == 2;
    const std::int32_t* nb = &bin_nbr_[bin * 27];
    for (int k = 0; k < 27; ++k) {
      if (nb[k] < 0) continue;
      const std::size_t b = std::size_t(nb[k]);
      for (std::uint32_t q = bin_start_[b]; q < bin_start_[b + 1]; ++q) {
        if (q == self) continue;
        const MP& o = parts_[q];
        if (norm2(o.x - P.x) >= r2 || !visible(P.cell, o)) continue;
        out.push_back({o.x, o.frame, o.h, surf && o.cell == P.cell});
      }
    }
  }

  void update(std::size_t i, std::size_t bin, std::vector<Cand>& buf, std::uint64_t& evals) {
    MP& P = parts_[i];
    gather(P, i, bin, hmax_ / kBeta + P.h, buf);
    Vec3 v;
    const double e0 = energy_at(P.x, P.frame, P.h, buf, &v, nullptr);
    P.energy = e0;
    P.delta = 0;
    const JunctionCell& c = cells_[std::size_t(P.cell)];
    Vec3 vt = c.count == 2 ? v - P.frame * dot(P.frame, v) : P.frame * dot(P.frame, v);
    if (!(norm2(vt) > 0)) return;
    const double lambda_max = kLambdaMaxPerH2 * P.h * P.h;
    double lambda = std::min(P.lambda, lambda_max);
    for (bool first = true;; first = false) {
      Vec3 x = P.x + vt * lambda, frame;
      double h = 0, resid = 0;
      if (place(c, x, frame, h, resid, kReprojectSteps, P.h, evals) && norm2(x - P.x) <= P.h * P.h) {
        const double e1 = energy_at(x, frame, h, buf, nullptr, nullptr);
        if (e1 <= e0) {
          P.x = x;
          P.frame = frame;
          P.h = h;
          P.resid = resid;
          P.energy = e1;
          P.delta = e1 - e0;
          P.lambda = first ? std::min(lambda * 10, lambda_max) : lambda;
          return;
        }
      }
      lambda /= 10;
      if (lambda <= kLambdaMin) {
        P.lambda = kLambdaMin;
        return;
      }
    }
  }

  void rebin();
  template <class Body>
  void for_each_bin(Body&& body);
  double sweep(double& energy);
  double measure();
  bool population_control(int level, std::uint64_t tag, bool final_check, MultiLevelStats& st);
  void keep_covered(std::vector<char>& del, std::size_t& ndel) const;
  std::size_t repair_junctions();
  std::vector<char> project_candidates(std::vector<Candidate>& cands, int steps, const std::vector<double>& max_step);
  void thin(std::vector<Candidate>& cands, double fraction);
  void add_particles(const std::vector<Candidate>& cands, const std::vector<char>& ok, int level);
  void relax(int level, MultiLevelStats& st);
  void prepare_visibility();
  std::int32_t cell_index(const JunctionCell& c) {
    auto it = cell_ids_.find(c);
    if (it != cell_ids_.end()) return it->second;
    const std::int32_t id = std::int32_t(cells_.size());
    cells_.push_back(c);
    cell_ids_.emplace(c, id);
    return id;
  }

  const MaterialSet& m_;
  const SizingField* sizing_;
  MultiParticleParams p_;
  Box domain_;
  double resolution_ = 0, tol_ = 0;
  double e_ideal_ = 0, split_below_ = 0, delete_above_ = 0;
  double hmax_ = 0, alpha_floor_ = 0;

  std::vector<JunctionCell> cells_;
  std::map<JunctionCell, std::int32_t> cell_ids_;
  std::vector<char> vis_;  // vis_[a * nc + b]: cell b bounds cell a (b ⊇ a, b != a)

  std::vector<MP> parts_, scratch_;
  std::uint64_t next_id_ = 0;
  std::uint64_t iteration_ = 0;

  std::vector<std::uint64_t> bin_key_;
  std::vector<std::uint32_t> bin_start_;
  std::vector<std::int32_t> bin_nbr_;
  std::vector<std::uint32_t> colour_start_, colour_bins_;
  std::vector<char> bin_active_;

  tbb::enumerable_thread_specific<std::vector<Cand>> tls_;
  std::atomic<std::uint64_t> evals_{0};
};

void MultiEngine::prepare_visibility() {
  const std::size_t nc = cells_.size();
  vis_.assign(nc * nc, 0);
  for (std::size_t a = 0; a < nc; ++a)
    for (std::size_t b = 0; b < nc; ++b)
      if (a != b && cells_[b].count > cells_[a].count && cells_[b].contains_all(cells_[a])) vis_[a * nc + b] = 1;
}

void MultiEngine::rebin() {
  const std::size_t n = parts_.size();
  Box bb;
  hmax_ = 0;
  for (const MP& q : parts_) {
    bb.extend(q.x);
    hmax_ = std::max(hmax_, q.h);
  }
  alpha_floor_ = kBeta / hmax_;
  double w = hmax_ / kBeta + 2 * hmax_;
  const Vec3 ext = bb.size();
  const double longest = std::max({ext.x, ext.y, ext.z, 0.0});
  w = std::max(w, longest / double(1 << 20));
  const std::uint64_t nx = std::uint64_t(std::floor(ext.x / w)) + 3, ny = std::uint64_t(std::floor(ext.y / w)) + 3;
  const Vec3 lo = bb.lo - Vec3{w, w, w};
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keys(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 t = (parts_[i].x - lo) / w;
    const std::uint64_t ix = std::uint64_t(std::max(0.0, t.x)), iy = std::uint64_t(std::max(0.0, t.y)),
                        iz = std::uint64_t(std::max(0.0, t.z));
    keys[i] = {ix + nx * (iy + ny * iz), std::uint32_t(i)};
  }
  std::sort(keys.begin(), keys.end());  // by bin, then previous order: deterministic
  scratch_.resize(n);
  for (std::size_t i = 0; i < n; ++i) scratch_[i] = parts_[keys[i].second];
  parts_.swap(scratch_);

  bin_key_.clear();
  bin_start_.clear();
  for (std::size_t i = 0; i < n; ++i)
    if (i == 0 || keys[i].first != keys[i - 1].first) {
      bin_key_.push_back(keys[i].first);
      bin_start_.push_back(std::uint32_t(i));
    }
  bin_start_.push_back(std::uint32_t(n));
  const std::size_t nb = bin_key_.size();
  std::unordered_map<std::uint64_t, std::int32_t> lookup;
  lookup.reserve(2 * nb);
  for (std::size_t b = 0; b < nb; ++b) lookup.emplace(bin_key_[b], std::int32_t(b));
  bin_nbr_.assign(nb * 27, -1);
  bin_active_.assign(nb, 0);
  std::vector<std::uint8_t> colour(nb);
  colour_start_.assign(kColours + 1, 0);
  for (std::size_t b = 0; b < nb; ++b) {
    const std::uint64_t k = bin_key_[b];
    const std::uint64_t ix = k % nx, iy = (k / nx) % ny, iz = k / (nx * ny);
    int q = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const std::uint64_t key = (ix + dx) + nx * ((iy + dy) + ny * (iz + dz));
          auto it = lookup.find(key);
          bin_nbr_[b * 27 + q++] = it == lookup.end() ? -1 : it->second;
        }
    for (std::uint32_t i = bin_start_[b]; i < bin_start_[b + 1]; ++i)
      if (!parts_[i].fixed) bin_active_[b] = 1;
    colour[b] = std::uint8_t((ix & 1) + 2 * (iy & 1) + 4 * (iz & 1));
    if (bin_active_[b]) ++colour_start_[colour[b] + 1];
  }
  for (int c = 0; c < kColours; ++c) colour_start_[c + 1] += colour_start_[c];
  colour_bins_.resize(colour_start_[kColours]);
  std::uint32_t fill[kColours];
  for (int c = 0; c < kColours; ++c) fill[c] = colour_start_[c];
  for (std::size_t b = 0; b < nb; ++b)
    if (bin_active_[b]) colour_bins_[fill[colour[b]]++] = std::uint32_t(b);
}

template <class Body>
void MultiEngine::for_each_bin(Body&& body) {
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, bin_key_.size(), 1),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      std::vector<Cand>& buf = tls_.local();
                      for (std::size_t b = r.begin(); b != r.end(); ++b) body(b, buf);
                    });
}

double MultiEngine::sweep(double& energy) {
  for (int colour = 0; colour < kColours; ++colour) {
    const std::uint32_t b0 = colour_start_[colour], b1 = colour_start_[colour + 1];
    if (b0 == b1) continue;
    pm::parallel_for(tbb::blocked_range<std::uint32_t>(b0, b1, 1), [&](const tbb::blocked_range<std::uint32_t>& r) {
      std::vector<Cand>& buf = tls_.local();
      std::uint64_t evals = 0;
      for (std::uint32_t k = r.begin(); k != r.end(); ++k) {
        const std::uint32_t b = colour_bins_[k];
        for (std::uint32_t i = bin_start_[b]; i < bin_start_[b + 1]; ++i)
          if (!parts_[i].fixed) update(i, b, buf, evals);
      }
      evals_ += evals;
    });
  }
  double de = 0;
  energy = 0;
  for (const MP& q : parts_)
    if (!q.fixed) {
      de += q.delta;
      energy += q.energy;
    }
  // Active-active pairs count twice in Σ E_i; active-fixed pairs once: 2 Σ
  // is an upper bound of the decrease, fine as a convergence measure.
  return -2 * de;
}

double MultiEngine::measure() {
  rebin();
  for_each_bin([&](std::size_t b, std::vector<Cand>& buf) {
    for (std::uint32_t i = bin_start_[b]; i < bin_start_[b + 1]; ++i) {
      MP& P = parts_[i];
      if (P.fixed) continue;
      gather(P, i, b, hmax_ / kBeta, buf);
      P.energy = energy_at(P.x, P.frame, P.h, buf, nullptr, nullptr);
    }
  });
  double e = 0;
  for (const MP& q : parts_)
    if (!q.fixed) e += q.energy;
  return e;
}

std::vector<char> MultiEngine::project_candidates(std::vector<Candidate>& cands, int steps,
                                                  const std::vector<double>& max_step) {
  std::vector<char> ok(cands.size(), 0);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, cands.size(), 16),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      std::uint64_t evals = 0;
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        Candidate& c = cands[i];
                        Vec3 x = c.x, frame;
                        double h = 0, resid = 0;
                        const double ms = max_step.empty() ? 0.0 : max_step[i];
                        if (place(cells_[std::size_t(c.cell)], x, frame, h, resid, steps, ms, evals)) {
                          c.x = x;
                          ok[i] = 1;
                        }
                      }
                      evals_ += evals;
                    });
  return ok;
}

// Greedy thinning in the candidates' order: drop a candidate closer than
// fraction × h to a kept one of the same cell.
void MultiEngine::thin(std::vector<Candidate>& cands, double fraction) {
  if (cands.empty() || fraction <= 0) return;
  std::vector<double> hs(cands.size(), 0);
  double hmax = 0;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    double h = 0;
    if (!spacing_at(cands[i].x, h)) h = sizing_ ? sizing_->min_value() : p_.spacing;
    hs[i] = fraction * h;
    hmax = std::max(hmax, hs[i]);
  }
  const double w = std::max(hmax, 1e-12);
  auto key = [&](const Vec3& x, int dx, int dy, int dz) {
    const std::int64_t ix = std::int64_t(std::floor(x.x / w)) + dx, iy = std::int64_t(std::floor(x.y / w)) + dy,
                       iz = std::int64_t(std::floor(x.z / w)) + dz;
    return mix64(std::uint64_t(ix) * 73856093ull ^ mix64(std::uint64_t(iy) * 19349663ull ^
                                                         mix64(std::uint64_t(iz) * 83492791ull)));
  };
  std::unordered_multimap<std::uint64_t, std::size_t> grid;
  std::vector<Candidate> kept;
  for (std::size_t i = 0; i < cands.size(); ++i) {
    const Candidate& c = cands[i];
    bool close = false;
    for (int dz = -1; dz <= 1 && !close; ++dz)
      for (int dy = -1; dy <= 1 && !close; ++dy)
        for (int dx = -1; dx <= 1 && !close; ++dx) {
          auto range = grid.equal_range(key(c.x, dx, dy, dz));
          for (auto it = range.first; it != range.second; ++it) {
            const Candidate& k = kept[it->second];
            if (k.cell == c.cell && norm2(k.x - c.x) < hs[i] * hs[i]) {
              close = true;
              break;
            }
          }
        }
    if (close) continue;
    grid.emplace(key(c.x, 0, 0, 0), kept.size());
    kept.push_back(c);
  }
  cands.swap(kept);
}

void MultiEngine::add_particles(const std::vector<Candidate>& cands, const std::vector<char>& ok, int level) {
  for (std::size_t i = 0; i < cands.size(); ++i) {
    if (!ok[i]) continue;
    MP q;
    q.x = cands[i].x;
    q.cell = cands[i].cell;
    q.level = level;
    // Re-evaluate frame/h/residual at the final point (cheap, exact).
    std::uint64_t ev = 0;
    Vec3 x = q.x;
    if (!place(cells_[std::size_t(q.cell)], x, q.frame, q.h, q.resid, 2, 0, ev)) continue;
    evals_ += ev;
    q.x = x;
    q.lambda = std::min(1.0, kLambdaMaxPerH2 * q.h * q.h);
    q.id = next_id_++;
    parts_.push_back(q);
  }
}

bool MultiEngine::population_control(int level, std::uint64_t tag, bool final_check, MultiLevelStats& st) {
  measure();
  std::vector<char> del(parts_.size(), 0);
  std::vector<Candidate> kids;
  std::vector<double> steps;
  std::size_t ndel = 0, nactive = 0;
  for (std::size_t i = 0; i < parts_.size(); ++i) {
    const MP& q = parts_[i];
    if (q.fixed) continue;
    ++nactive;
    const double biased = q.energy * (1 + uniform01(p_.seed, q.id, tag, kStreamPopulation)) / 2;
    if (biased > delete_above_) {
      del[i] = 1;
      ++ndel;
    } else if (biased < split_below_) {
      const double u = uniform01(p_.seed, q.id, tag, kStreamSplitDir);
      Vec3 off;
      if (cells_[std::size_t(q.cell)].count == 3) {
        off = q.frame * (u < 0.5 ? 0.5 * q.h : -0.5 * q.h);
      } else {
        const Vec3 a = std::fabs(q.frame.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
        const Vec3 t1 = normalized(cross(q.frame, a)), t2 = cross(q.frame, t1);
        off = (t1 * std::cos(2 * kPi * u) + t2 * std::sin(2 * kPi * u)) * (0.5 * q.h);
      }
      kids.push_back({q.x + off, q.cell, i});
      steps.push_back(q.h);
    }
  }
  keep_covered(del, ndel);
  if (final_check && double(ndel + kids.size()) <= p_.population_tolerance * double(nactive)) return false;
  if (ndel == nactive && ndel) {  // never empty a level
    for (std::size_t i = 0; i < parts_.size(); ++i)
      if (del[i]) {
        del[i] = 0;
        --ndel;
        break;
      }
  }
  const std::vector<char> ok = project_candidates(kids, 20, steps);
  scratch_.clear();
  for (std::size_t i = 0; i < parts_.size(); ++i)
    if (!del[i]) scratch_.push_back(parts_[i]);
  parts_.swap(scratch_);
  const std::size_t before = parts_.size();
  add_particles(kids, ok, level);
  const std::size_t nsplit = parts_.size() - before;
  st.splits += nsplit;
  st.deletions += ndel;
  return nsplit + ndel > 0;
}

// Crowded neighbours all have high energies, so they can all be marked for
// deletion in the same round and leave a hole (a short junction curve then
// loses every particle). In bin order, a marked particle is only deleted
// when a particle of its cell that stays lies within its interaction
// radius; otherwise it stays. Deterministic; needs the bins of measure().
void MultiEngine::keep_covered(std::vector<char>& del, std::size_t& ndel) const {
  for (std::size_t b = 0; b + 1 < bin_start_.size(); ++b)
    for (std::uint32_t i = bin_start_[b]; i < bin_start_[b + 1]; ++i) {
      if (!del[i]) continue;
      const MP& P = parts_[i];
      bool covered = false;
      const std::int32_t* nb = &bin_nbr_[b * 27];
      for (int k = 0; k < 27 && !covered; ++k) {
        if (nb[k] < 0) continue;
        const std::size_t c = std::size_t(nb[k]);
        for (std::uint32_t q = bin_start_[c]; q < bin_start_[c + 1] && !covered; ++q) {
          const MP& o = parts_[q];
          if (q == i || del[q] || o.fixed || o.cell != P.cell) continue;
          const double al = alpha(P.h, o.h);
          covered = al * al * norm2(o.x - P.x) < 1.0;
        }
      }
      if (!covered) {
        del[i] = 0;
        --ndel;
      }
    }
}

// After the surfaces: two surface particles of different interfaces that
// share a material ({a,b}, {a,c}) closer than a quarter spacing sit where the
// interfaces meet on a triple curve that the curve level did not sample
// (tightening moves junctions; seeds are only near most of them). Such a
// pair is replaced by one particle projected onto the triple junction
// {a,b,c}, when the projection lands within half a spacing and no curve or
// point particle is already there. Otherwise the Delaunay mesh gets a sliver
// spanning the two interfaces. Sequential in bin order: deterministic.
std::size_t MultiEngine::repair_junctions() {
  rebin();
  const std::size_t n = parts_.size();
  std::vector<char> gone(n, 0);
  std::vector<MP> added;
  std::uint64_t ev = 0;
  auto near_junction = [&](const Vec3& x, std::size_t bin, double r) {
    const std::int32_t* nb = &bin_nbr_[bin * 27];
    for (int k = 0; k < 27; ++k) {
      if (nb[k] < 0) continue;
      for (std::uint32_t q = bin_start_[std::size_t(nb[k])]; q < bin_start_[std::size_t(nb[k]) + 1]; ++q)
        if (parts_[q].level < 2 && norm2(parts_[q].x - x) < r * r) return true;
    }
    for (const MP& a : added)
      if (norm2(a.x - x) < r * r) return true;
    return false;
  };
  for (std::size_t b = 0; b + 1 < bin_start_.size(); ++b)
    for (std::uint32_t i = bin_start_[b]; i < bin_start_[b + 1]; ++i) {
      if (gone[i] || parts_[i].level != 2) continue;
      const JunctionCell& ci = cells_[std::size_t(parts_[i].cell)];
      const std::int32_t* nb = &bin_nbr_[b * 27];
      for (int k = 0; k < 27 && !gone[i]; ++k) {
        if (nb[k] < 0) continue;
        for (std::uint32_t j = bin_start_[std::size_t(nb[k])]; j < bin_start_[std::size_t(nb[k]) + 1]; ++j) {
          const MP& P = parts_[i];
          const MP& Q = parts_[j];
          if (j == i || gone[j] || Q.level != 2 || Q.cell == P.cell) continue;
          const double hmin = std::min(P.h, Q.h);
          if (norm2(Q.x - P.x) >= 0.0625 * hmin * hmin) continue;
          const JunctionCell& cj = cells_[std::size_t(Q.cell)];
          std::vector<int> mats(ci.m.begin(), ci.m.begin() + 2);
          for (int t = 0; t < 2; ++t)
            if (!ci.contains(cj.m[std::size_t(t)])) mats.push_back(cj.m[std::size_t(t)]);
          if (mats.size() != 3) continue;  // disjoint pairs: not one triple junction
          const Vec3 mid = (P.x + Q.x) * 0.5;
          MP q;
          q.x = mid;
          q.cell = cell_index(make_cell(mats));
          if (!place(cells_[std::size_t(q.cell)], q.x, q.frame, q.h, q.resid, 20, hmin, ev)) continue;
          if (norm2(q.x - mid) >= 0.25 * hmin * hmin || near_junction(q.x, b, 0.5 * q.h)) continue;
          q.level = 1;
          q.fixed = true;
          q.lambda = std::min(1.0, kLambdaMaxPerH2 * q.h * q.h);
          q.id = next_id_++;
          added.push_back(q);
          gone[i] = gone[j] = 1;
          break;
        }
      }
    }
  evals_ += ev;
  if (added.empty()) return 0;
  scratch_.clear();
  for (std::size_t i = 0; i < n; ++i)
    if (!gone[i]) scratch_.push_back(parts_[i]);
  for (const MP& q : added) scratch_.push_back(q);
  parts_.swap(scratch_);
  return added.size();
}

void MultiEngine::relax(int level, MultiLevelStats& st) {
  const int n_ideal = level == 1 ? 2 : 6;
  double d = 0;
  e_ideal_ = n_ideal * particle_pair_energy(p_.energy, kBeta, d);
  split_below_ = (level == 1 ? 0.25 : 0.35) * e_ideal_;
  delete_above_ = (level == 1 ? 2.5 : 1.75) * e_ideal_;
  std::size_t active = 0;
  for (const MP& q : parts_) active += q.fixed ? 0 : 1;
  if (active == 0) return;
  std::optional<Progress> progress;
  if (p_.progress) progress.emplace(level == 1 ? "curves" : "surfaces", std::size_t(p_.max_iters));
  int since = 0;
  bool conv_final = false;
  for (int it = 0; it < p_.max_iters; ++it) {
    rebin();
    double e = 0;
    const double change = sweep(e);
    ++iteration_;
    ++st.iterations;
    ++since;
    const bool conv = change <= p_.tolerance * e;
    if (p_.progress) {
      char detail[96];
      std::snprintf(detail, sizeof detail, "%zu particles, dE %.3g%%", parts_.size(),
                    e > 0 ? 100 * change / e : 0.0);
      progress->update(std::size_t(it + 1), detail);
    }
    if (conv || since >= p_.population_interval) {
      since = 0;
      const bool changed = population_control(level, iteration_, conv, st);
      if (conv && !changed) {
        conv_final = true;
        break;
      }
    }
  }
  st.converged = conv_final;
  st.energy_final = measure();
  std::size_t n = 0;
  for (const MP& q : parts_) n += q.fixed ? 0 : 1;
  st.energy_ideal = double(n) * e_ideal_;
}

MultiParticleResult MultiEngine::run(const std::vector<JunctionSeed>& seeds) {
  MultiParticleResult res;
  // Seeds -> cells (material indices), per level.
  std::map<int, int> index_of;
  for (std::size_t i = 0; i < m_.labels.size(); ++i) index_of[m_.labels[i]] = int(i);
  std::array<std::vector<Candidate>, 3> by_level;
  for (std::size_t k = 0; k < seeds.size(); ++k) {
    const JunctionSeed& s = seeds[k];
    if (!is_finite(s.x))
      throw InputError("seed " + std::to_string(k) + " is not finite: " + fmt(s.x) +
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
    by_level[std::size_t(level)].push_back({s.x, cell_index(make_cell(mats)), k});
  }
  prepare_visibility();

  for (int level = 0; level < 3; ++level) {
    if (level == 2 && !p_.surfaces) break;
    MultiLevelStats& st = res.levels[std::size_t(level)];
    Stopwatch sw;
    std::vector<Candidate>& cands = by_level[std::size_t(level)];
    std::size_t given = cands.size();
    if (level > 0) thin(cands, p_.seed_thinning);
    const std::size_t after_thin = cands.size();
    std::vector<char> ok = project_candidates(cands, p_.seed_project_steps, {});
    std::size_t failed = 0;
    for (char c : ok) failed += c ? 0 : 1;
    st.seeds_failed = failed;
    if (level == 0) {  // cull duplicates of one quadruple point
      std::vector<Candidate> good;
      for (std::size_t i = 0; i < cands.size(); ++i)
        if (ok[i]) good.push_back(cands[i]);
      const std::size_t n_good = good.size();
      thin(good, p_.cull_fraction);
      st.seeds_culled = n_good - good.size();
      cands.swap(good);
      ok.assign(cands.size(), 1);
    } else {
      st.seeds_culled = given - after_thin;
    }
    const std::size_t before = parts_.size();
    add_particles(cands, ok, level);
    debug("level " + std::to_string(level) + ": " + std::to_string(parts_.size() - before) + " particles from " +
          std::to_string(given) + " seeds");
    if (level > 0) relax(level, st);
    std::vector<char> has(cells_.size(), 0);
    st.particles = 0;
    for (MP& q : parts_)
      if (!q.fixed) {
        ++st.particles;
        has[std::size_t(q.cell)] = 1;
        q.fixed = true;
      }
    for (char h : has) st.cells += h ? 1 : 0;
    st.seconds = sw.seconds();
  }
  std::size_t surfaces = p_.surfaces ? res.levels[2].particles : res.levels[1].particles + res.levels[0].particles;
  if (surfaces == 0) {
    std::string labels;
    for (int l : m_.labels) labels += (labels.empty() ? "" : ",") + std::to_string(l);
    throw InputError("no material interface found: none of the " + std::to_string(seeds.size()) +
                     " seeds reached a junction of the materials " + labels +
                     " (do the materials touch? are the seeds from the same label map?)");
  }

  if (p_.surfaces && p_.repair_junctions) res.junction_repairs = repair_junctions();

  // Output, level by level, in a deterministic order (level, then bin order).
  std::stable_sort(parts_.begin(), parts_.end(), [](const MP& a, const MP& b) { return a.level < b.level; });
  const std::size_t n = parts_.size();
  res.positions.resize(n);
  res.normals.resize(n);
  res.junction.resize(n);
  res.labels.resize(n);
  res.spacing.resize(n);
  res.energy.resize(n);
  res.residual.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const MP& q = parts_[i];
    const JunctionCell& c = cells_[std::size_t(q.cell)];
    res.positions[i] = q.x;
    res.normals[i] = c.count == 2 ? q.frame : Vec3{};
    res.junction[i] = c.count;
    std::array<int, 4> l{{-1, -1, -1, -1}};
    for (int k = 0; k < c.count; ++k) l[std::size_t(k)] = m_.labels[std::size_t(c.m[std::size_t(k)])];
    std::sort(l.begin(), l.begin() + c.count);
    res.labels[i] = l;
    res.spacing[i] = q.h;
    res.energy[i] = q.energy;
    res.residual[i] = q.resid;
    res.max_residual = std::max(res.max_residual, q.resid);
  }
  res.field_evaluations = evals_.load();
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
      throw InputError(quote(what) + ": vertex " + std::to_string(i) + " is not finite: " + fmt(s.x));
    const double j = jn[i];
    if (!(j == 2 || j == 3 || j == 4))
      throw InputError(quote(what) + ": vertex " + std::to_string(i) + " has junction " + fmt(j) +
                       "; expected 2, 3 or 4");
    s.count = int(j);
    for (int k = 0; k < s.count; ++k) {
      const double v = (*lab[k])[i];
      if (!(v >= 0) || v != std::floor(v) || v > 2147483647.0)
        throw InputError(quote(what) + ": vertex " + std::to_string(i) + " has label " + fmt(v) +
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
    if (len / h > 511) throw InputError("seed grid too fine: " + fmt(len / h) + " nodes along an axis (at most 512)");
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
    throw UsageError("spacing must be > 0 world units, got " + fmt(p.spacing));
  if (sizing && !(sizing->min_value() > 0))
    throw InputError("sizing field " + quote(sizing->name()) + " has h <= 0 (min " + fmt(sizing->min_value()) +
                     "); expected h > 0 world units");
  if (!(p.tolerance > 0)) throw UsageError("tolerance must be > 0, got " + fmt(p.tolerance));
  if (p.max_iters < 1) throw UsageError("max iterations must be >= 1, got " + std::to_string(p.max_iters));
  if (p.population_interval < 1)
    throw UsageError("population interval must be >= 1, got " + std::to_string(p.population_interval));
  if (!(p.population_tolerance >= 0))
    throw UsageError("population tolerance must be >= 0, got " + fmt(p.population_tolerance));
  if (p.seed_project_steps < 1)
    throw UsageError("seed projection steps must be >= 1, got " + std::to_string(p.seed_project_steps));
  if (seeds.empty()) throw InputError("no junction seeds given; expected mcinit --junctions points or a label map");
  MultiEngine engine(m, sizing, p);
  const Box& dom = engine.domain();
  if (dom.lo.x >= dom.hi.x || dom.lo.y >= dom.hi.y || dom.lo.z >= dom.hi.z)
    throw InputError("the materials' domains do not overlap (intersection " + fmt(dom.lo) + " - " + fmt(dom.hi) +
                     "); expected volumes covering the same box");
  if (!sizing && p.spacing > norm(dom.size()))
    throw UsageError("spacing " + fmt(p.spacing) + " is larger than the domain's diagonal " + fmt(norm(dom.size())));
  return engine.run(seeds);
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
