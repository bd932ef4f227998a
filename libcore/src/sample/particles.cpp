#include "pm/sample/particles.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <string>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/base/parallel.h"

// Binning invariant (why 3x3x3 bins are enough and why colours make it
// race-free).
//
// Bins are rebuilt at the start of every sweep from the current positions.
// During a sweep each particle moves at most once, by at most its local
// spacing d_i <= D (trial moves longer than that are rejected), so any
// particle's current position is within D of the position it was binned at.
// A particle i evaluates trial positions within d_i <= D of its binned
// position; a pair interacts only when closer than its interaction radius
// 1/α_ij <= R (α is bounded from below). Hence an interacting pair's binned
// positions are closer than R + 2D, and with bins of width W >= R + 2D every
// interaction partner sits in the 3x3x3 block around i's bin. Within that
// block a particle only looks at those within its own reach (interaction
// radius bound from its local spacing, plus its step), which matters when
// spacings vary a lot (sizing fields, strong adaptivity).
//
// Colours: bin (bx,by,bz) has colour (bx%2) + 2(by%2) + 4(bz%2). A particle
// writes only itself and reads only particles of the 3x3x3 block around its
// bin. Two distinct bins A, B of one colour differ by >= 2 along some axis,
// so A lies outside B's block and vice versa: nothing a bin writes is read or
// written by another bin of the same colour, so they can run concurrently
// without races and the outcome does not depend on how they are scheduled.
// (The 27-colour scheme (b%3) keeps whole blocks disjoint, which is more than
// needed and costs 27 instead of 8 synchronisations per sweep.) Colours run
// in a fixed order, particles within a bin in a fixed order: the result is
// bit-identical for any thread count.

namespace pm {
namespace {

constexpr double kPi = 3.14159265358979323846;
const double kBeta = 0.5 / std::cos(kPi / 6);  // 1-ring at |r| = β ≈ 0.577
constexpr double kEpsR = 1e-7;                 // added to |r|
constexpr double kGamma = 0.156;               // normal weighting
constexpr double kLambda0 = 1.0;
constexpr double kLambdaMin = 1e-14;
constexpr double kLambdaMaxPerS2 = 100.0;      // λ_i <= 100 s_i² (world units² per energy unit)
constexpr double kEpsF = 1e-5;
constexpr int kProjectSteps = 20;              // Newton steps for initial points and new particles
constexpr int kReprojectSteps = 4;             // Newton steps after a tangent move
constexpr double kSplitBelow = 0.35, kDeleteAbove = 1.75;
constexpr double kSizingSlack = 1.25;          // sizing: pair radius cap = 1.25 × largest h / β
constexpr double kSpacingSlack = 1.5;          // a move may grow the local spacing by at most this factor
constexpr int kMaxLevels = 8;
constexpr int kColours = 8;                    // bin colours (bx%2, by%2, bz%2), see above
constexpr std::size_t kSerialBelow = 2000;     // sweeps of fewer particles run on one thread
constexpr double kGatherMargin = 0.25;         // first gather covers trial moves up to 0.25 s_i
constexpr double kListSkin = 0.5;              // neighbour lists: a particle may drift 0.5 s_i before a rebuild
constexpr double kHoleRadius = 1.5;            // an anchor without a particle within 1.5 s_i is a hole
constexpr int kMaxRefills = 4;                 // refill rounds on the final level

// ---------------------------------------------------------------------------
// Counter-based randomness: a hash of (seed, particle id, iteration, stream).
std::uint64_t mix64(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
double uniform01(std::uint64_t seed, std::uint64_t id, std::uint64_t iter, std::uint64_t stream) {
  std::uint64_t h = mix64(seed ^ 0x5851F42D4C957F2Dull);
  h = mix64(h ^ id);
  h = mix64(h ^ (iter * 0xD1B54A32D192ED03ull));
  h = mix64(h ^ (stream * 0x8CB92BA72F3D8DD7ull));
  return double(h >> 11) * 0x1.0p-53;
}
enum Stream : std::uint64_t { kStreamPopulation = 1, kStreamSplitDir, kStreamInitX, kStreamInitY, kStreamInitZ,
                              kStreamQuad };

void tangent_basis(const Vec3& n, Vec3& t1, Vec3& t2) {
  const Vec3 a = std::fabs(n.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  t1 = normalized(cross(n, a));
  t2 = cross(n, t1);
}

// Curvedness sqrt(κ1² + κ2²) = ‖P H P‖_F / |∇F| (the shape operator's only
// non-zero eigenvalues are κ1, κ2, so its Frobenius norm is the curvedness).
double curvedness_of(const Vec3& g, const Mat3& h) {
  const double gn = norm(g);
  if (!(gn > 0)) return 0;
  const Vec3 n = g / gn;
  Mat3 p = Mat3::identity() - outer(n, n);
  const Mat3 php = p * h * p;
  double s = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) s += php.m[i][j] * php.m[i][j];
  return std::sqrt(s) / gn;
}

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

// One particle, POD, stored in one flat vector.
struct Particle {
  Vec3 x;             // position on F = iso
  Vec3 grad;          // ∇F at x
  Vec3 normal;        // ∇F/|∇F|
  double attr = 0;    // curvedness C (curvature mode) or h(x) (sizing mode)
  double spacing = 0; // local spacing s_i = β/α_ii (also the step cap)
  double lambda = kLambda0;
  double energy = 0;
  double delta = 0;   // energy change of the last move (E_new - E_old, <= 0)
  double moved = 0;   // length of the last move / spacing
  std::uint64_t id = 0;
  std::int32_t neighbours = 0;
};

// A neighbour as seen by the particle being updated (copied for locality).
struct Cand {
  Vec3 x, n;
  double attr;
};

// Result of evaluating F (and the adaptivity attribute) at a point.
struct Eval {
  double f = 0;
  Vec3 g;
  double attr = 0;
};

class Engine {
 public:
  Engine(const ScalarField& field, const SizingField* sizing, const ParticleParams& p)
      : field_(field), sizing_(sizing), p_(p), domain_(field.domain()) {
    curvature_mode_ = sizing_ == nullptr;
    need_hessian_ = curvature_mode_ && p_.density > 0;
    e_ideal_ = particle_ideal_energy(p_.energy);
  }

  ParticleResult run(const std::vector<Vec3>& seeds);

 private:
  // --- adaptivity ----------------------------------------------------------
  double alpha(double ai, double aj) const {
    if (curvature_mode_) {
      const double a = kBeta * (1.0 + k_curv_ * 0.5 * (ai + aj)) / s_;
      return std::min(a, alpha_cap_);
    }
    const double a = kBeta / (scale_ * std::min(ai, aj));
    return std::max(a, alpha_floor_);
  }
  double local_spacing(double attr) const { return kBeta / alpha(attr, attr); }
  // Upper bound on the interaction radius 1/α_ij of particle i with local
  // spacing s_i and any partner: β/α_ij = s/(1 + k (C_i + C_j)/2) <= 2 s_i
  // (curvature mode), = min(h_i, h_j) <= h_i (sizing), = s (uniform).
  double radius_bound(double spacing) const {
    return std::min(r_max_, (need_hessian_ ? 2.0 : 1.0) * spacing / kBeta);
  }
  // The scale (coarse-to-fine level 2^k, or the fixed-count adaptation)
  // multiplies the whole local spacing: curvature mode s/(1 + ρ s C/(2π)),
  // sizing mode h. (Scaling s inside the adaptivity term would leave the
  // curvature-limited spacing 2π/(ρ C) unchanged on coarse levels.)
  void set_scale(double scale) {
    scale_ = scale;
    s_ = p_.spacing * scale;
    k_curv_ = p_.density * p_.spacing / (2 * kPi);
    alpha_cap_ = p_.alpha_cap * kBeta / s_;
    lists_valid_ = false;
  }

  // --- field access (counted) -------------------------------------------------
  // F - iso and its gradient; `full` adds the attribute (curvedness needs the
  // Hessian; sizing needs h). Returns false when the point is unusable.
  // Outside the sizing field's box: fails when `strict`, else attr = -1.
  bool eval(const Vec3& x, Eval& e, bool full, std::uint64_t& count, bool strict = true) const {
    ++count;
    if (full && need_hessian_) {
      Mat3 h;
      e.f = field_.evaluate(x, e.g, h) - p_.iso;
      e.attr = curvedness_of(e.g, h);
    } else {
      e.f = field_.value_gradient(x, e.g) - p_.iso;
    }
    if (!std::isfinite(e.f) || !is_finite(e.g)) return false;
    if (full && sizing_ && !sizing_->sample(x, e.attr)) {
      if (strict) return false;
      e.attr = -1;
    }
    return true;
  }
  // Newton projection x <- x - F ∇F/|∇F|² from x, up to `steps` steps, until
  // |F| <= ε_F (at least one step). On success x and e hold the result.
  bool project(Vec3& x, Eval& e, int steps, std::uint64_t& count, bool strict = true) const {
    Eval cur;
    if (!eval(x, cur, false, count)) return false;
    for (int k = 0; k < steps; ++k) {
      const double gg = norm2(cur.g);
      if (!(gg > 1e-300)) return false;
      x -= cur.g * (cur.f / gg);
      if (!is_finite(x) || !domain_.contains(x)) return false;
      if (!eval(x, cur, true, count, strict)) return false;
      if (std::fabs(cur.f) <= kEpsF) {
        e = cur;
        return true;
      }
    }
    return false;
  }
  Particle make_particle(const Vec3& x, const Eval& e, std::uint64_t id) const {
    Particle q;
    q.x = x;
    q.grad = e.g;
    q.normal = normalized(e.g);
    q.attr = curvature_mode_ ? (need_hessian_ ? e.attr : 0.0) : e.attr;
    q.spacing = local_spacing(q.attr);
    q.lambda = std::min(kLambda0, kLambdaMaxPerS2 * q.spacing * q.spacing);
    q.id = id;
    return q;
  }

  // --- energy -------------------------------------------------------------------
  // E_i at x (normal n, attribute a) against the candidates; optionally the
  // repulsion velocity v = -∂E/∂x and the neighbour count.
  double energy_at(const Vec3& x, const Vec3& n, double a, const std::vector<Cand>& cs, Vec3* v,
                   int* nbrs) const {
    double e = 0;
    Vec3 force;
    int count = 0;
    for (const Cand& c : cs) {
      const Vec3 d = x - c.x;
      const double d2 = norm2(d);
      const double al = alpha(a, c.attr);
      if (al * al * d2 >= 1.0) continue;
      ++count;
      const double w = normal_weight(dot(n, c.n));
      if (w == 0) continue;
      const double dist = std::sqrt(d2);
      double de = 0;
      e += w * particle_pair_energy(p_.energy, al * dist + kEpsR, de);
      if (v && dist > 0) force -= d * (w * de * al / dist);
    }
    if (v) *v = force;
    if (nbrs) *nbrs = count;
    return e;
  }

  // Candidates within `reach` of x from the 3x3x3 block of `cell`, excluding
  // self. A neighbour bin is skipped when x lies farther than reach + d_max
  // from it along an axis: its particles were binned inside it and have
  // moved at most d_max since, so none of them can be within reach.
  void gather(const Vec3& x, double reach, std::size_t self, std::size_t cell, std::vector<Cand>& out) const {
    out.clear();
    const double r2 = reach * reach;
    const std::int32_t* nb = &cell_nbr_[cell * 27];
    const std::uint64_t key = cell_key_[cell];
    const std::uint64_t ix = key % nx_, iy = (key / nx_) % ny_, iz = key / (nx_ * ny_);
    const double slack = reach + d_max_;
    // Per axis, bit 0/1/2 = neighbour offset -1/0/+1 may hold candidates.
    auto axis_mask = [&](double xa, double lo, std::uint64_t i) {
      const double c0 = lo + double(i) * cell_w_, c1 = c0 + cell_w_;
      return (xa - slack < c0 ? 1 : 0) | 2 | (xa + slack >= c1 ? 4 : 0);
    };
    const int mx = axis_mask(x.x, grid_lo_.x, ix), my = axis_mask(x.y, grid_lo_.y, iy),
              mz = axis_mask(x.z, grid_lo_.z, iz);
    for (int k = 0; k < 27; ++k) {
      if (nb[k] < 0) continue;
      if (!((mx >> (k % 3)) & 1) || !((my >> ((k / 3) % 3)) & 1) || !((mz >> (k / 9)) & 1)) continue;
      const std::size_t c = std::size_t(nb[k]);
      for (std::uint32_t q = cell_start_[c]; q < cell_start_[c + 1]; ++q) {
        if (norm2(pos_[q] - x) >= r2 || q == self) continue;
        const Particle& o = parts_[q];
        out.push_back({o.x, o.normal, o.attr});
      }
    }
  }

  // Candidates within `reach` of x from particle i's cached neighbour list
  // (a superset of every particle that can come within reach of any trial
  // position of i until the lists are stale, see build_lists()).
  void gather_list(const Vec3& x, double reach, std::size_t i, std::vector<Cand>& out) const {
    out.clear();
    const double r2 = reach * reach;
    for (std::uint32_t k = nbr_start_[i]; k < nbr_start_[i + 1]; ++k) {
      const std::uint32_t q = nbr_[k];
      if (norm2(pos_[q] - x) >= r2) continue;
      const Particle& o = parts_[q];
      out.push_back({o.x, o.normal, o.attr});
    }
  }

  // --- the moves (SPEC §3, adaptive step size) ------------------------------------
  void update(std::size_t i, std::size_t cell, std::vector<Cand>& buf, std::uint64_t& count) {
    Particle& P = parts_[i];
    // Trial positions lie within s_i of x_i and may not grow the local
    // spacing beyond kSpacingSlack s_i, which bounds their interaction radius.
    const bool varying = need_hessian_ || !curvature_mode_;
    const double spacing_cap = varying ? kSpacingSlack * P.spacing : P.spacing;
    // Candidates for the current position and for trial positions within
    // `margin` of it; a longer trial gathers again with the full step s_i.
    // Either way every particle within interaction range of the evaluated
    // point is in `buf`, in the same order, so the sums are the same.
    const double radius = radius_bound(spacing_cap);
    const double margin = kGatherMargin * P.spacing;
    bool full_reach = false;
    if (use_lists_)
      gather_list(P.x, radius + margin, i, buf);
    else
      gather(P.x, radius + margin, i, cell, buf);
    Vec3 v;
    const double e0 = energy_at(P.x, P.normal, P.attr, buf, &v, nullptr);
    P.energy = e0;
    P.delta = 0;
    P.moved = 0;
    const double gg = norm2(P.grad);
    const Vec3 vt = v - P.grad * (dot(P.grad, v) / gg);
    if (!(norm2(vt) > 0)) return;
    const double lambda_max = kLambdaMaxPerS2 * P.spacing * P.spacing;
    double lambda = std::min(P.lambda, lambda_max);
    const double step_cap2 = P.spacing * P.spacing;
    for (bool first = true;; first = false) {
      Vec3 x = P.x + vt * lambda;
      Eval e;
      const bool on_surface = project(x, e, kReprojectSteps, count) && norm2(x - P.x) <= step_cap2;
      const double attr = on_surface ? (curvature_mode_ ? (need_hessian_ ? e.attr : 0.0) : e.attr) : 0.0;
      if (on_surface && (!varying || local_spacing(attr) <= spacing_cap)) {
        const Vec3 n = normalized(e.g);
        if (!full_reach && norm2(x - P.x) > margin * margin) {
          if (use_lists_)
            gather_list(P.x, radius + P.spacing, i, buf);
          else
            gather(P.x, radius + P.spacing, i, cell, buf);
          full_reach = true;
        }
        const double e1 = energy_at(x, n, attr, buf, nullptr, nullptr);
        if (e1 <= e0) {
          P.moved = std::sqrt(norm2(x - P.x)) / P.spacing;
          P.x = x;
          pos_[i] = x;
          P.grad = e.g;
          P.normal = n;
          P.attr = attr;
          P.spacing = local_spacing(attr);
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

  // --- bins -------------------------------------------------------------------------
  // Sort the particles into bins of width r_max + 2 d_max (a 3x3x3 gather
  // with one sweep of drift), or wide enough for the lists' reach
  // (`for_lists`, see build_lists()).
  void rebin(bool for_lists = false);
  // Cached neighbour lists (SPEC §3.7), built right after rebin(): particle
  // i lists every j within L_i + k_j of it, L_i = radius_bound(t_i t_i s_i) +
  // t_i s_i + k_i, where t_i = kSpacingSlack where the spacing varies (its
  // spacing may grow that much before a rebuild, and a move's cap by that much
  // again), else 1, and k = kListSkin × spacing is the drift allowed before a
  // rebuild. All local: small particles keep short lists in a graded field. Lists are rebuilt when any particle drifted farther than its k_i
  // or its spacing outgrew t_i's assumption; then every particle within
  // interaction range of any trial position is still listed. L_i <= the bin
  // width, so the bin colouring still keeps parallel updates apart.
  void build_lists();
  bool lists_stale() const;
  // One Gauss-Seidel sweep. Returns the decrease of the system energy
  // Σ_i E_i, exactly 2 Σ_i (E_old - E_new) over the accepted moves because
  // E_ij = E_ji (α and w are symmetric); `energy` receives Σ_i E_i as seen
  // by the sweep (each E_i when particle i was updated).
  double sweep(double& energy);
  double measure();
  template <class Body>
  void for_each_cell_parallel(Body&& body);

  // --- system control -------------------------------------------------------------
  // Split/delete towards the ideal energy. When `final_check` and at most
  // population_tolerance × N particles want to change, nothing is applied
  // and the population counts as stable. Returns whether it changed.
  bool population_control(std::uint64_t tag, bool final_check);
  // Anchors (the projected initial points) and holes. Needs valid bins.
  // Index of the particle nearest to anchor a among those within
  // kHoleRadius × its local spacing with a normal on the same side and not
  // `dead`, or -1.
  std::int64_t anchor_cover(const Particle& a, const std::vector<char>* dead) const;
  // Final level: add a particle at every anchor that has none near it (in
  // anchor order, skipping anchors the added ones cover). Returns the count.
  std::size_t refill_holes();
  // Clear deletion marks so that no covered anchor loses its last cover.
  void keep_anchor_covers(std::vector<char>& del, std::size_t& ndel) const;
  std::int32_t find_cell(std::uint64_t key) const;
  bool adapt_spacing();
  void split_all_into_four(std::uint64_t tag);
  bool relax_level(int level, int levels);
  void initialise(const std::vector<Vec3>& seeds, double lattice_step);
  // Linear-interpolated crossings of F = iso on the edges of a lattice with
  // the given step over the domain (deterministic order).
  std::vector<Vec3> lattice_crossings(double step);
  int coarse_levels(double base) const;
  // Project candidate points in parallel; returns success flags and results.
  void project_many(const std::vector<Vec3>& xs, std::vector<Vec3>& out, std::vector<Eval>& evals,
                    std::vector<char>& ok);

  const ScalarField& field_;
  const SizingField* sizing_;
  ParticleParams p_;
  Box domain_;
  bool curvature_mode_ = true, need_hessian_ = false;
  double e_ideal_ = 0;

  double scale_ = 1, s_ = 0, k_curv_ = 0, alpha_cap_ = 1e300, alpha_floor_ = 0;
  double r_max_ = 0, d_max_ = 0, cell_w_ = 0;

  std::vector<Particle> parts_, scratch_;
  std::vector<Particle> anchors_;  // projected initial points (empty with a fixed count)
  bool guard_anchors_ = false;     // final level: refill holes, keep anchor covers
  std::vector<Vec3> pos_;  // copy of parts_[i].x, compact for neighbour scans (valid after rebin)
  std::uint64_t next_id_ = 0;

  // bins (flat arrays reused across iterations)
  std::vector<std::uint64_t> keys_, keys_tmp_;
  std::vector<std::uint32_t> order_, order_tmp_, radix_count_;
  std::vector<std::uint64_t> cell_key_;
  std::vector<std::uint32_t> cell_start_;
  std::vector<std::int32_t> cell_nbr_;
  std::vector<std::uint32_t> hash_;
  std::vector<std::uint32_t> colour_start_, colour_cells_;
  std::vector<std::uint8_t> colour_of_cell_;
  std::uint64_t nx_ = 0, ny_ = 0, nz_ = 0;
  Vec3 grid_lo_;

  // neighbour lists (CSR) and the state they were built for
  std::vector<std::uint32_t> nbr_start_, nbr_;
  std::vector<Vec3> list_x_;
  std::vector<double> list_s_;
  bool lists_valid_ = false;
  bool use_lists_ = false;  // sweeps gather from the lists (else from the bins)
  double max_move_ = 1e300; // largest move of the last sweep / spacing

  tbb::enumerable_thread_specific<std::vector<Cand>> tls_;
  std::atomic<std::uint64_t> evals_{0};

  ParticleResult res_;
  std::uint64_t iteration_ = 0;
};

void Engine::rebin(bool for_lists) {
  const std::size_t n = parts_.size();
  Box bb;
  double dmax = 0, hmax = 0;
  for (const Particle& q : parts_) {
    bb.extend(q.x);
    dmax = std::max(dmax, q.spacing);
    if (!curvature_mode_) hmax = std::max(hmax, scale_ * q.attr);
  }
  if (curvature_mode_) {
    r_max_ = s_ / kBeta;  // α_ij >= β/s
  } else {
    r_max_ = kSizingSlack * hmax / kBeta;
    alpha_floor_ = 1.0 / r_max_;
    dmax = 0;
    for (Particle& q : parts_) {
      q.spacing = local_spacing(q.attr);
      dmax = std::max(dmax, q.spacing);
    }
  }
  d_max_ = dmax;
  lists_valid_ = false;
  double w = r_max_ + (for_lists ? kSpacingSlack + 2 * kListSkin : 2.0) * d_max_;
  // Keep the grid's index space reasonable (wider bins are always correct).
  const Vec3 ext = bb.size();
  const double longest = std::max({ext.x, ext.y, ext.z, 0.0});
  w = std::max(w, longest / double(1 << 20));
  cell_w_ = w;
  const Vec3 lo = bb.lo - Vec3{w, w, w};
  grid_lo_ = lo;
  nx_ = std::uint64_t(std::floor(ext.x / w)) + 3;
  ny_ = std::uint64_t(std::floor(ext.y / w)) + 3;
  nz_ = std::uint64_t(std::floor(ext.z / w)) + 3;

  keys_.resize(n);
  keys_tmp_.resize(n);
  order_.resize(n);
  order_tmp_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 t = (parts_[i].x - lo) / w;
    const std::uint64_t ix = std::min<std::uint64_t>(std::uint64_t(std::max(0.0, t.x)), nx_ - 2);
    const std::uint64_t iy = std::min<std::uint64_t>(std::uint64_t(std::max(0.0, t.y)), ny_ - 2);
    const std::uint64_t iz = std::min<std::uint64_t>(std::uint64_t(std::max(0.0, t.z)), nz_ - 2);
    keys_[i] = ix + nx_ * (iy + ny_ * iz);
    order_[i] = std::uint32_t(i);
  }
  // LSD radix sort of (key, index): counting sort per 11-bit digit; stable,
  // so particles keep their previous relative order within a bin.
  const std::uint64_t total = nx_ * ny_ * nz_;
  int bits = 1;
  while (bits < 64 && (std::uint64_t(1) << bits) < total) ++bits;
  constexpr int kDigit = 11;
  radix_count_.resize(std::size_t(1) << kDigit);
  for (int shift = 0; shift < bits; shift += kDigit) {
    std::fill(radix_count_.begin(), radix_count_.end(), 0u);
    const std::uint64_t mask = (std::uint64_t(1) << kDigit) - 1;
    for (std::size_t i = 0; i < n; ++i) ++radix_count_[(keys_[i] >> shift) & mask];
    std::uint32_t sum = 0;
    for (auto& c : radix_count_) {
      const std::uint32_t t = c;
      c = sum;
      sum += t;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t slot = radix_count_[(keys_[i] >> shift) & mask]++;
      keys_tmp_[slot] = keys_[i];
      order_tmp_[slot] = order_[i];
    }
    keys_.swap(keys_tmp_);
    order_.swap(order_tmp_);
  }
  scratch_.resize(n);
  for (std::size_t i = 0; i < n; ++i) scratch_[i] = parts_[order_[i]];
  parts_.swap(scratch_);
  pos_.resize(n);
  for (std::size_t i = 0; i < n; ++i) pos_[i] = parts_[i].x;

  // Cells: runs of equal keys.
  cell_key_.clear();
  cell_start_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    if (i == 0 || keys_[i] != keys_[i - 1]) {
      cell_key_.push_back(keys_[i]);
      cell_start_.push_back(std::uint32_t(i));
    }
  }
  cell_start_.push_back(std::uint32_t(n));
  const std::size_t nc = cell_key_.size();

  // Open-addressing hash key -> cell index + 1.
  std::size_t hsize = 16;
  while (hsize < 2 * nc) hsize *= 2;
  hash_.assign(hsize, 0u);
  const std::size_t hmask = hsize - 1;
  for (std::size_t c = 0; c < nc; ++c) {
    std::size_t h = mix64(cell_key_[c]) & hmask;
    while (hash_[h]) h = (h + 1) & hmask;
    hash_[h] = std::uint32_t(c + 1);
  }
  cell_nbr_.resize(nc * 27);
  colour_start_.assign(kColours + 1, 0u);
  std::vector<std::uint8_t>& colour = colour_of_cell_;
  colour.resize(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    const std::uint64_t k = cell_key_[c];
    const std::uint64_t ix = k % nx_, iy = (k / nx_) % ny_, iz = k / (nx_ * ny_);
    int m = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const std::uint64_t key = (ix + dx) + nx_ * ((iy + dy) + ny_ * (iz + dz));
          cell_nbr_[c * 27 + m++] = find_cell(key);
        }
    colour[c] = std::uint8_t((ix & 1) + 2 * (iy & 1) + 4 * (iz & 1));
    ++colour_start_[colour[c] + 1];
  }
  for (int c = 0; c < kColours; ++c) colour_start_[c + 1] += colour_start_[c];
  colour_cells_.resize(nc);
  std::uint32_t fill[kColours];
  for (int c = 0; c < kColours; ++c) fill[c] = colour_start_[c];
  for (std::size_t c = 0; c < nc; ++c) colour_cells_[fill[colour[c]]++] = std::uint32_t(c);
}


void Engine::build_lists() {
  const std::size_t n = parts_.size();
  const bool varying = need_hessian_ || !curvature_mode_;
  const double step_factor = varying ? kSpacingSlack : 1.0;
  list_x_.resize(n);
  list_s_.resize(n);
  nbr_start_.assign(n + 1, 0u);
  // Two passes over the 3x3x3 blocks (count, then fill at the prefix sums):
  // deterministic for any schedule, one flat array.
  auto scan = [&](std::size_t c, bool fill) {
    const std::int32_t* nb = &cell_nbr_[c * 27];
    for (std::uint32_t i = cell_start_[c]; i < cell_start_[c + 1]; ++i) {
      const Particle& P = parts_[i];
      // i's reach: interaction radius at the largest spacing its trial moves
      // may reach before a rebuild, plus the longest trial step, plus its own
      // drift; each candidate j adds its own drift allowance.
      const double reach =
          radius_bound(step_factor * step_factor * P.spacing) + step_factor * P.spacing + kListSkin * P.spacing;
      std::uint32_t count = 0, at = fill ? nbr_start_[i] : 0;
      for (int k = 0; k < 27; ++k) {
        if (nb[k] < 0) continue;
        const std::size_t cc = std::size_t(nb[k]);
        for (std::uint32_t q = cell_start_[cc]; q < cell_start_[cc + 1]; ++q) {
          const double rq = reach + kListSkin * parts_[q].spacing;
          if (q == i || norm2(pos_[q] - P.x) >= rq * rq) continue;
          if (fill)
            nbr_[at++] = q;
          else
            ++count;
        }
      }
      if (!fill) nbr_start_[i + 1] = count;
    }
  };
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, cell_key_.size(), 4),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t c = r.begin(); c != r.end(); ++c) scan(c, false);
                    });
  for (std::size_t i = 0; i < n; ++i) nbr_start_[i + 1] += nbr_start_[i];
  nbr_.resize(nbr_start_[n]);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, cell_key_.size(), 4),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t c = r.begin(); c != r.end(); ++c) scan(c, true);
                    });
  for (std::size_t i = 0; i < n; ++i) {
    list_x_[i] = parts_[i].x;
    list_s_[i] = parts_[i].spacing;
  }
  lists_valid_ = true;
  ++res_.list_builds;
}

bool Engine::lists_stale() const {
  if (!lists_valid_ || list_x_.size() != parts_.size()) return true;
  const bool varying = need_hessian_ || !curvature_mode_;
  const double step_factor = varying ? kSpacingSlack : 1.0;
  for (std::size_t i = 0; i < parts_.size(); ++i) {
    const double k = kListSkin * list_s_[i];
    if (norm2(pos_[i] - list_x_[i]) > k * k) return true;
    // The trial step is capped by the current spacing: it may not outgrow
    // the step the list allowed for (uniform spacing never changes).
    if (varying && parts_[i].spacing > step_factor * list_s_[i]) return true;
  }
  return false;
}

std::int32_t Engine::find_cell(std::uint64_t key) const {
  const std::size_t hmask = hash_.size() - 1;
  std::size_t h = mix64(key) & hmask;
  while (hash_[h]) {
    const std::uint32_t c = hash_[h] - 1;
    if (cell_key_[c] == key) return std::int32_t(c);
    h = (h + 1) & hmask;
  }
  return -1;
}

std::int64_t Engine::anchor_cover(const Particle& a, const std::vector<char>* dead) const {
  const double R = kHoleRadius * local_spacing(a.attr);
  // The grid spans the particles' box grown by one cell (width >= R), so an
  // anchor outside it has no particle within R.
  const Vec3 t = (a.x - grid_lo_) / cell_w_;
  if (!(t.x >= 1 && t.y >= 1 && t.z >= 1)) return -1;
  const std::uint64_t ix = std::uint64_t(t.x), iy = std::uint64_t(t.y), iz = std::uint64_t(t.z);
  if (ix + 1 >= nx_ || iy + 1 >= ny_ || iz + 1 >= nz_) return -1;
  std::int64_t best = -1;
  double best_d2 = R * R;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const std::int32_t c = find_cell((ix + dx) + nx_ * ((iy + dy) + ny_ * (iz + dz)));
        if (c < 0) continue;
        for (std::uint32_t q = cell_start_[c]; q < cell_start_[c + 1]; ++q) {
          const double d2 = norm2(pos_[q] - a.x);
          if (d2 >= best_d2 || (dead && (*dead)[q]) || dot(parts_[q].normal, a.normal) <= 0) continue;
          best_d2 = d2;
          best = q;
        }
      }
  return best;
}

std::size_t Engine::refill_holes() {
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
    const double R = kHoleRadius * local_spacing(a.attr);
    bool near = false;
    for (std::size_t i : added)
      if (norm2(parts_[i].x - a.x) < R * R && dot(parts_[i].normal, a.normal) > 0) {
        near = true;
        break;
      }
    if (near) continue;
    Particle q = a;
    q.spacing = local_spacing(q.attr);
    q.lambda = std::min(kLambda0, kLambdaMaxPerS2 * q.spacing * q.spacing);
    q.energy = q.delta = 0;
    q.id = next_id_++;
    added.push_back(parts_.size());
    parts_.push_back(q);
  }
  res_.refilled += added.size();
  return added.size();
}

void Engine::keep_anchor_covers(std::vector<char>& del, std::size_t& ndel) const {
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

template <class Body>
void Engine::for_each_cell_parallel(Body&& body) {
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, cell_key_.size(), 1),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      std::vector<Cand>& buf = tls_.local();
                      for (std::size_t c = r.begin(); c != r.end(); ++c) body(c, buf);
                    });
}

double Engine::sweep(double& energy) {
  // Small systems run on the calling thread: eight parallel_for rounds per
  // sweep cost more than they save below a few thousand particles (same
  // result either way, see the colouring argument above).
  const bool serial = parts_.size() < kSerialBelow;
  for (int colour = 0; colour < kColours; ++colour) {
    const std::uint32_t b = colour_start_[colour], e = colour_start_[colour + 1];
    if (b == e) continue;
    if (serial) {
      std::vector<Cand>& buf = tls_.local();
      std::uint64_t count = 0;
      for (std::uint32_t k = b; k != e; ++k) {
        const std::uint32_t c = colour_cells_[k];
        for (std::uint32_t i = cell_start_[c]; i < cell_start_[c + 1]; ++i) update(i, c, buf, count);
      }
      evals_ += count;
      continue;
    }
    pm::parallel_for(tbb::blocked_range<std::uint32_t>(b, e, 1), [&](const tbb::blocked_range<std::uint32_t>& r) {
      std::vector<Cand>& buf = tls_.local();
      std::uint64_t count = 0;
      for (std::uint32_t k = r.begin(); k != r.end(); ++k) {
        const std::uint32_t c = colour_cells_[k];
        for (std::uint32_t i = cell_start_[c]; i < cell_start_[c + 1]; ++i) update(i, c, buf, count);
      }
      evals_ += count;
    });
  }
  double de = 0;
  energy = 0;
  max_move_ = 0;
  for (const Particle& q : parts_) {
    de += q.delta;
    energy += q.energy;
    max_move_ = std::max(max_move_, q.moved);
  }
  return -2 * de;
}

// Fresh energies and neighbour counts at the current positions (Jacobi: pure
// reads of the others, so any schedule gives the same numbers).
double Engine::measure() {
  rebin();
  for_each_cell_parallel([&](std::size_t c, std::vector<Cand>& buf) {
    for (std::uint32_t i = cell_start_[c]; i < cell_start_[c + 1]; ++i) {
      Particle& P = parts_[i];
      gather(P.x, radius_bound(P.spacing), i, c, buf);
      int nb = 0;
      P.energy = energy_at(P.x, P.normal, P.attr, buf, nullptr, &nb);
      P.neighbours = nb;
    }
  });
  double e = 0;
  for (const Particle& q : parts_) e += q.energy;
  return e;
}

void Engine::project_many(const std::vector<Vec3>& xs, std::vector<Vec3>& out, std::vector<Eval>& evals,
                          std::vector<char>& ok) {
  const std::size_t n = xs.size();
  out = xs;
  evals.assign(n, Eval{});
  ok.assign(n, 0);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, n, 16), [&](const tbb::blocked_range<std::size_t>& r) {
    std::uint64_t count = 0;
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      Vec3 x = xs[i];
      Eval e;
      if (project(x, e, kProjectSteps, count, false)) {
        out[i] = x;
        evals[i] = e;
        ok[i] = 1;
      }
    }
    evals_ += count;
  });
}

Vec3 tangent_offset(const Vec3& n, double angle, double dist) {
  Vec3 t1, t2;
  tangent_basis(n, t1, t2);
  return (t1 * std::cos(angle) + t2 * std::sin(angle)) * dist;
}

std::vector<Vec3> Engine::lattice_crossings(double step) {
  const Vec3 lo = domain_.lo, sz = domain_.size();
  const double longest = std::max({sz.x, sz.y, sz.z});
  step = std::max(step, longest / 256);  // at most ~17M lattice nodes
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
          const double v = field_.value(node(i, j, k)) - p_.iso;
          f[i + nx * (j + ny * k)] = std::isfinite(v) ? float(v) : 0.0f;
        }
    evals_ += r.size() * nx * ny;
  });
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

int Engine::coarse_levels(double base) const {
  if (!p_.coarse_to_fine || p_.count != 0) return 0;
  const double start = p_.coarse_start > 0 ? p_.coarse_start : 4 * field_.resolution();
  int levels = 0;
  while (levels < kMaxLevels && base * std::ldexp(1.0, levels + 1) <= start * (1 + 1e-9)) ++levels;
  return levels;
}

void Engine::initialise(const std::vector<Vec3>& seeds, double lattice_step) {
  std::vector<Vec3> xs;
  if (seeds.empty() && lattice_step > 0) xs = lattice_crossings(lattice_step);
  if (!xs.empty()) {
    // lattice crossings: projected below like random points
  } else if (!seeds.empty()) {
    for (std::size_t k = 0; k < seeds.size(); ++k)
      if (!is_finite(seeds[k]))
        throw InputError("seed point " + std::to_string(k) + " is not finite: " + fmt(seeds[k]) +
                         "; expected finite world coordinates");
    xs = seeds;
  } else {
    const Vec3 lo = domain_.lo, sz = domain_.size();
    xs.resize(p_.init_count);
    for (std::size_t k = 0; k < xs.size(); ++k)
      xs[k] = lo + Vec3{sz.x * uniform01(p_.seed, k, 0, kStreamInitX), sz.y * uniform01(p_.seed, k, 0, kStreamInitY),
                        sz.z * uniform01(p_.seed, k, 0, kStreamInitZ)};
  }
  std::vector<Vec3> out;
  std::vector<Eval> ev;
  std::vector<char> ok;
  project_many(xs, out, ev, ok);
  parts_.clear();
  std::size_t dropped = 0, outside = 0;
  Vec3 example;
  for (std::size_t k = 0; k < xs.size(); ++k) {
    if (!ok[k]) {
      ++dropped;
      continue;
    }
    if (sizing_ && !(ev[k].attr > 0)) {
      if (outside++ == 0) example = out[k];
      continue;
    }
    parts_.push_back(make_particle(out[k], ev[k], next_id_++));
  }
  if (outside)
    throw InputError("sizing field " + quote(sizing_->name()) + " does not cover the surface: " +
                     std::to_string(outside) + " particle(s) on F = " + fmt(p_.iso) + " lie outside its box " +
                     fmt(sizing_->bounds().lo) + " - " + fmt(sizing_->bounds().hi) + ", e.g. at " + fmt(example));
  res_.dropped_init = dropped;
  if (!p_.count) anchors_ = parts_;
  if (parts_.empty())
    throw InputError("no surface found: none of the " + std::to_string(xs.size()) + " initial points reached F = " +
                     fmt(p_.iso) + " within " + std::to_string(kProjectSteps) + " Newton steps (" +
                     field_.describe() + "); check the isovalue and the seeds");

  if (p_.count) {
    if (parts_.size() > p_.count) parts_.resize(p_.count);
    for (int round = 0; parts_.size() < p_.count; ++round) {
      if (round > 64)
        throw InputError("could not place " + std::to_string(p_.count) + " particles on the surface (got " +
                         std::to_string(parts_.size()) + ")");
      const std::size_t need = std::min(parts_.size(), p_.count - parts_.size());
      std::vector<Vec3> kids(need);
      for (std::size_t i = 0; i < need; ++i) {
        const Particle& q = parts_[i];
        const double angle = 2 * kPi * uniform01(p_.seed, q.id, std::uint64_t(round), kStreamSplitDir);
        kids[i] = q.x + tangent_offset(q.normal, angle, 0.3 * q.spacing);
      }
      project_many(kids, out, ev, ok);
      for (std::size_t i = 0; i < need; ++i)
        if (ok[i] && (!sizing_ || ev[i].attr > 0)) parts_.push_back(make_particle(out[i], ev[i], next_id_++));
    }
  }
}

bool Engine::population_control(std::uint64_t tag, bool final_check) {
  measure();
  const std::size_t n = parts_.size();
  std::vector<char> del(n, 0);
  std::vector<Vec3> kids;
  std::size_t ndel = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Particle& q = parts_[i];
    // Biased energy E_i (1 + u)/2, u uniform on [0, 1]: neighbours with
    // similar energies do not all split or die together.
    const double biased = q.energy * (1 + uniform01(p_.seed, q.id, tag, kStreamPopulation)) / 2;
    if (biased > kDeleteAbove * e_ideal_) {
      del[i] = 1;
      ++ndel;
    } else if (biased < kSplitBelow * e_ideal_) {
      const double angle = 2 * kPi * uniform01(p_.seed, q.id, tag, kStreamSplitDir);
      kids.push_back(q.x + tangent_offset(q.normal, angle, 0.5 * q.spacing));
    }
  }
  keep_anchor_covers(del, ndel);
  if (final_check && double(ndel + kids.size()) <= p_.population_tolerance * double(n)) return false;
  if (ndel == n) {  // never empty the system
    del[0] = 0;
    --ndel;
  }
  std::vector<Vec3> out;
  std::vector<Eval> ev;
  std::vector<char> ok;
  project_many(kids, out, ev, ok);
  scratch_.clear();
  for (std::size_t i = 0; i < n; ++i)
    if (!del[i]) scratch_.push_back(parts_[i]);
  std::size_t nsplit = 0;
  for (std::size_t k = 0; k < kids.size(); ++k) {
    if (!ok[k] || (sizing_ && !(ev[k].attr > 0))) continue;
    scratch_.push_back(make_particle(out[k], ev[k], next_id_++));
    ++nsplit;
  }
  parts_.swap(scratch_);
  res_.splits += nsplit;
  res_.deletions += ndel;
  return nsplit + ndel > 0;
}

// Fixed count: scale s so that the mean particle energy approaches the ideal
// one. Near the hexagonal packing E ∝ s^4.7 (cotangent), hence the exponent.
bool Engine::adapt_spacing() {
  const double e = measure();
  const double mean = e / double(parts_.size());
  double factor = mean > 0 ? std::pow(e_ideal_ / mean, 0.2) : 2.0;
  factor = std::clamp(factor, 0.5, 2.0);
  if (std::fabs(factor - 1) <= 0.01) return false;
  set_scale(scale_ * factor);
  for (Particle& q : parts_) q.spacing = local_spacing(q.attr);
  return true;
}

void Engine::split_all_into_four(std::uint64_t tag) {
  const std::size_t n = parts_.size();
  std::vector<Vec3> kids(4 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const Particle& q = parts_[i];
    Vec3 t1, t2;
    tangent_basis(q.normal, t1, t2);
    const double th = 2 * kPi * uniform01(p_.seed, q.id, tag, kStreamQuad);
    const Vec3 a = (t1 * std::cos(th) + t2 * std::sin(th)) * (0.25 * q.spacing);
    const Vec3 b = (t2 * std::cos(th) - t1 * std::sin(th)) * (0.25 * q.spacing);
    kids[4 * i + 0] = q.x + a + b;
    kids[4 * i + 1] = q.x - a + b;
    kids[4 * i + 2] = q.x - a - b;
    kids[4 * i + 3] = q.x + a - b;
  }
  std::vector<Vec3> out;
  std::vector<Eval> ev;
  std::vector<char> ok;
  project_many(kids, out, ev, ok);
  set_scale(scale_ / 2);
  scratch_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    bool first = true;
    for (int c = 0; c < 4; ++c) {
      const std::size_t k = 4 * i + c;
      if (!ok[k] || (sizing_ && !(ev[k].attr > 0))) continue;
      scratch_.push_back(make_particle(out[k], ev[k], first ? parts_[i].id : next_id_++));
      first = false;
    }
  }
  if (!scratch_.empty()) parts_.swap(scratch_);
  else
    for (Particle& q : parts_) q.spacing = local_spacing(q.attr);
}

bool Engine::relax_level(int level, int levels) {
  Progress progress(levels > 1 ? "level " + std::to_string(levels - level) + "/" + std::to_string(levels) : "relax",
                    std::size_t(p_.max_iters));
  // Convergence: the exact decrease of the system energy in one sweep,
  // relative to the system energy (the sweep's sum, accurate enough as a
  // scale); not disturbed by the staleness of Gauss-Seidel energies.
  int since = 0, refills = 0;
  for (int it = 0; it < p_.max_iters; ++it) {
    Stopwatch sw;
    if (!use_lists_) {
      rebin();  // gather from the bins, rebuilt every sweep
    } else if (lists_stale()) {
      rebin(true);
      build_lists();
    }
    double e = 0;
    const double change = sweep(e);
    // Lists pay off once particles move slowly (a list then serves many
    // sweeps); while they still move fast, the bins rebuilt every sweep are
    // cheaper than lists rebuilt every sweep.
    const bool slow = max_move_ < 0.25 * kListSkin;
    if (slow != use_lists_) {
      use_lists_ = slow;
      lists_valid_ = false;
    }
    res_.seconds_relax += sw.seconds();
    ++iteration_;
    ++res_.iterations;
    res_.particle_updates += parts_.size();
    ++since;
    const bool conv = change <= p_.tolerance * e;
    if (p_.progress) {
      char detail[96];
      std::snprintf(detail, sizeof detail, "%zu particles, dE %.3g%%", parts_.size(),
                    e > 0 ? 100 * change / e : 0.0);
      progress.update(std::size_t(it + 1), detail);
    }
    if (conv || since >= p_.population_interval) {
      since = 0;
      Stopwatch sp;
      bool changed = false;
      if (p_.count)
        changed = adapt_spacing();
      else if (p_.population_control)
        changed = population_control(iteration_, conv);
      res_.seconds_population += sp.seconds();
      if (conv && !changed) {
        if (guard_anchors_ && refills < kMaxRefills) {
          Stopwatch sr;
          const std::size_t added = refill_holes();
          res_.seconds_population += sr.seconds();
          if (added > 0) {
            ++refills;
            debug("refilled " + std::to_string(added) + " hole(s) left by coarser levels");
            continue;
          }
        }
        return true;
      }
    }
  }
  return false;
}

ParticleResult Engine::run(const std::vector<Vec3>& seeds) {
  set_scale(1.0);
  Stopwatch sw;
  int levels = curvature_mode_ ? coarse_levels(p_.spacing) : 0;
  // Lattice step ≈ 1.15 × the starting spacing: a plane crosses on average
  // 1.5 lattice edges per step², the hexagonal packing has 1.155 per s².
  double lattice_step = 0;
  if (p_.init_lattice && seeds.empty()) {
    if (curvature_mode_)
      lattice_step = 1.15 * p_.spacing * std::ldexp(1.0, levels);
    else
      lattice_step = 1.15 * (p_.coarse_to_fine && p_.count == 0
                                 ? (p_.coarse_start > 0 ? p_.coarse_start : 4 * field_.resolution())
                                 : sizing_->min_value());
  }
  initialise(seeds, lattice_step);
  res_.seconds_init = sw.seconds();

  if (!curvature_mode_ && p_.coarse_to_fine && p_.count == 0) {  // the median h over the initial particles
    std::vector<double> h(parts_.size());
    for (std::size_t i = 0; i < h.size(); ++i) h[i] = parts_[i].attr;
    std::nth_element(h.begin(), h.begin() + std::ptrdiff_t(h.size() / 2), h.end());
    levels = coarse_levels(h[h.size() / 2]);
  }
  set_scale(std::ldexp(1.0, levels));
  for (Particle& q : parts_) q.spacing = local_spacing(q.attr);
  res_.levels = levels + 1;

  bool conv = false;
  for (int level = levels; level >= 0; --level) {
    if (level == 0 && levels > 0) {  // from here on every anchor keeps a particle near it
      guard_anchors_ = true;
      refill_holes();
    }
    conv = relax_level(level, levels + 1);
    debug("level " + std::to_string(levels - level + 1) + "/" + std::to_string(levels + 1) + ": " +
          std::to_string(parts_.size()) + " particles, " + std::to_string(res_.iterations) + " iterations so far" +
          (conv ? "" : " (not converged)"));
    if (level > 0) {
      Stopwatch sp;
      split_all_into_four(iteration_);
      res_.seconds_population += sp.seconds();
    }
  }
  res_.converged = conv;

  Stopwatch sf;
  const double e = measure();
  const std::size_t n = parts_.size();
  res_.positions.resize(n);
  res_.normals.resize(n);
  res_.energy.resize(n);
  res_.spacing.resize(n);
  res_.curvature.resize(n);
  std::uint64_t nb = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Particle& q = parts_[i];
    res_.positions[i] = q.x;
    res_.normals[i] = q.normal;
    res_.energy[i] = q.energy;
    res_.spacing[i] = q.spacing;
    nb += std::uint64_t(q.neighbours);
  }
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, n, 64), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      Vec3 g;
      Mat3 h;
      field_.evaluate(res_.positions[i], g, h);
      res_.curvature[i] = curvedness_of(g, h);
    }
    evals_ += r.size();
  });
  res_.energy_final = e;
  res_.energy_ideal = double(n) * e_ideal_;
  res_.mean_neighbours = n ? double(nb) / double(n) : 0.0;
  res_.final_spacing = curvature_mode_ ? s_ : scale_;
  res_.field_evaluations = evals_.load();
  res_.seconds_finish = sf.seconds();
  return std::move(res_);
}

}  // namespace

double particle_pair_energy(ParticleEnergy e, double r, double& dE_dr) {
  if (r >= 1.0) {
    dE_dr = 0;
    return 0;
  }
  if (e == ParticleEnergy::radial) {
    dE_dr = 1.0 - 1.0 / (r * r);
    return 1.0 / r - 2.0 + r;
  }
  const double a = 0.5 * kPi * r;
  const double sn = std::sin(a), cs = std::cos(a);
  dE_dr = 0.5 * kPi * (1.0 - 1.0 / (sn * sn));
  return cs / sn + a - 0.5 * kPi;
}

double particle_ideal_energy(ParticleEnergy e) {
  double d = 0;
  return 6.0 * particle_pair_energy(e, kBeta, d);
}

ParticleResult distribute_particles(const ScalarField& field, const std::vector<Vec3>& seeds,
                                    const SizingField* sizing, const ParticleParams& params) {
  const Box dom = field.domain();
  if (dom.empty()) throw InputError("distribute_particles: the field " + field.describe() + " has an empty domain");
  const double diag = norm(dom.size());
  if (!sizing && (!(params.spacing > 0) || !std::isfinite(params.spacing)))
    throw UsageError("spacing must be > 0 world units, got " + fmt(params.spacing));
  if (!sizing && params.spacing > diag)
    throw UsageError("spacing " + fmt(params.spacing) + " is larger than the domain's diagonal " + fmt(diag) +
                     " (world units); expected a spacing well below the size of the surface");
  if (!(params.density >= 0) || !std::isfinite(params.density))
    throw UsageError("density must be >= 0 particles per radian, got " + fmt(params.density));
  if (!(params.alpha_cap >= 1)) throw UsageError("alpha cap must be >= 1, got " + fmt(params.alpha_cap));
  if (!(params.tolerance > 0)) throw UsageError("tolerance must be > 0, got " + fmt(params.tolerance));
  if (!(params.population_tolerance >= 0))
    throw UsageError("population tolerance must be >= 0, got " + fmt(params.population_tolerance));
  if (params.max_iters < 1) throw UsageError("max iterations must be >= 1, got " + std::to_string(params.max_iters));
  if (params.population_interval < 1)
    throw UsageError("population interval must be >= 1, got " + std::to_string(params.population_interval));
  if (seeds.empty() && params.init_count == 0) throw UsageError("init count must be >= 1 when no seeds are given");
  Engine engine(field, sizing, params);
  return engine.run(seeds);
}

}  // namespace pm
