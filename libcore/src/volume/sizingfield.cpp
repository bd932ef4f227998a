#include "pm/volume/sizingfield.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>

#include "pm/base/error.h"
#include "pm/base/parallel.h"
#include "pm/field/curvature.h"
#include "pm/field/volume_field.h"
#include "pm/volume/medialaxis.h"

namespace pm {
namespace {

// A small static k-d tree for nearest-point queries (median splits along the
// widest axis, leaves of up to 8 points stored contiguously). Every node keeps
// the tight bounding box of its points; the search visits the nearer child
// first and skips a subtree whose box is no nearer than the best point so far
// (tight boxes prune far better than split planes on medial sheets, where
// many points lie at almost the same distance). It can start from a known
// upper bound, e.g. the distance to the previous query's nearest point.
// The result is the exact minimum whatever the bound, so it does not depend
// on the order of the queries.
class KdTree {
 public:
  explicit KdTree(const std::vector<Vec3>& pts) {
    std::vector<std::size_t> idx(pts.size());
    std::iota(idx.begin(), idx.end(), std::size_t(0));
    nodes_.reserve(2 * pts.size() / kLeaf + 2);
    build(pts, idx, 0, idx.size());
    pts_.resize(pts.size());
    for (std::size_t i = 0; i < idx.size(); ++i) pts_[i] = pts[idx[i]];
  }

  /// Squared distance from x to the nearest point, and that point's index
  /// (in the tree's order) in `at`. `bound2`: an upper bound on the answer
  /// (the squared distance to some point), or infinity.
  double nearest2(const Vec3& x, std::size_t& at, double bound2 = 1e300) const {
    double best = bound2;
    if (box_d2(nodes_[0], x) < best) search(0, x, best, at);
    return best;
  }
  const Vec3& point(std::size_t at) const { return pts_[at]; }
  std::size_t size() const { return pts_.size(); }

 private:
  static constexpr std::size_t kLeaf = 8;
  struct Node {
    std::size_t begin, end;  // leaf range in pts_
    int axis = -1;           // -1: leaf
    double split = 0;
    std::size_t left = 0, right = 0;
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};  // tight bounding box of the node's points
  };

  static double box_d2(const Node& n, const Vec3& x) {
    double s = 0;
    for (int a = 0; a < 3; ++a) {
      const double u = std::max(n.lo[a] - x[a], 0.0) + std::max(x[a] - n.hi[a], 0.0);
      s += u * u;
    }
    return s;
  }

  std::size_t build(const std::vector<Vec3>& pts, std::vector<std::size_t>& idx, std::size_t b, std::size_t e) {
    const std::size_t id = nodes_.size();
    nodes_.push_back({b, e});
    Box box;
    for (std::size_t i = b; i < e; ++i) box.extend(pts[idx[i]]);
    for (int a = 0; a < 3; ++a) {
      nodes_[id].lo[a] = box.lo[a];
      nodes_[id].hi[a] = box.hi[a];
    }
    if (e - b <= kLeaf) return id;
    const Vec3 s = box.size();
    const int axis = s.x >= s.y && s.x >= s.z ? 0 : (s.y >= s.z ? 1 : 2);
    const std::size_t m = b + (e - b) / 2;
    std::nth_element(idx.begin() + long(b), idx.begin() + long(m), idx.begin() + long(e),
                     [&](std::size_t u, std::size_t v) { return pts[u][axis] < pts[v][axis]; });
    const double split = pts[idx[m]][axis];
    const std::size_t l = build(pts, idx, b, m);
    const std::size_t r = build(pts, idx, m, e);
    nodes_[id].axis = axis;
    nodes_[id].split = split;
    nodes_[id].left = l;
    nodes_[id].right = r;
    return id;
  }

  // Called only when the node's box is nearer than best.
  void search(std::size_t id, const Vec3& x, double& best, std::size_t& at) const {
    const Node& n = nodes_[id];
    if (n.axis < 0) {
      for (std::size_t i = n.begin; i < n.end; ++i) {
        const double d2 = norm2(pts_[i] - x);
        if (d2 < best || (d2 == best && i < at)) {
          best = d2;
          at = i;
        }
      }
      return;
    }
    const double dl = box_d2(nodes_[n.left], x), dr = box_d2(nodes_[n.right], x);
    const bool left_first = dl <= dr;
    const std::size_t c1 = left_first ? n.left : n.right, c2 = left_first ? n.right : n.left;
    const double d1 = left_first ? dl : dr, d2 = left_first ? dr : dl;
    if (d1 < best) search(c1, x, best, at);
    if (d2 < best) search(c2, x, best, at);
  }

  std::vector<Vec3> pts_;
  std::vector<Node> nodes_;
};

bool same_grid(const Volume& a, const Volume& b) {
  if (!(a.dims() == b.dims())) return false;
  const Geometry &ga = a.geometry(), &gb = b.geometry();
  const double tol = 1e-6 * std::min(ga.spacing(0), std::min(ga.spacing(1), ga.spacing(2)));
  if (norm(ga.origin - gb.origin) > tol) return false;
  for (int c = 0; c < 3; ++c)
    if (norm(ga.directions.column(c) - gb.directions.column(c)) > tol) return false;
  return true;
}

}  // namespace

SizingFieldResult sizing_field(const std::vector<SizingSurface>& surfaces, const SizingFieldParams& p) {
  if (!(p.eps > 0) || !std::isfinite(p.eps))
    throw UsageError("sizing_field: eps " + std::to_string(p.eps) + " is invalid; expected > 0");
  if (!(p.hmin >= 0) || !std::isfinite(p.hmin))
    throw UsageError("sizing_field: hmin " + std::to_string(p.hmin) + " is invalid; expected >= 0 (world units)");
  if (!(p.band > 0)) throw UsageError("sizing_field: band " + std::to_string(p.band) + " is invalid; expected > 0 voxels");
  if (!(p.contraction >= 1))
    throw UsageError("sizing_field: contraction " + std::to_string(p.contraction) + " is invalid; expected >= 1");
  if (surfaces.empty()) throw UsageError("sizing_field: no surfaces given");

  const Volume& first = surfaces.front().sdf;
  const Dims& n = first.dims();
  const Geometry& g = first.geometry();
  const double hs = std::min(g.spacing(0), std::min(g.spacing(1), g.spacing(2)));
  const double hmax = std::max(g.spacing(0), std::max(g.spacing(1), g.spacing(2)));
  const double band = p.band * hs, C = 2 * p.eps / (p.contract ? p.contraction : 1.0);
  const double floor = 1e-3 * hs;  // a known value stays > 0 even on a degenerate medial axis
  for (std::size_t s = 0; s < surfaces.size(); ++s) {
    const std::string what = "sizing_field: surface " + std::to_string(s + 1) +
                             (surfaces[s].name.empty() ? "" : " (" + quote(surfaces[s].name) + ")");
    require_distance_volume(surfaces[s].sdf, what);
    if (surfaces[s].medial_axis.empty())
      throw InputError(what + ": the medial axis has no points; expected medial-axis points of that surface");
    if (s > 0 && !same_grid(surfaces[s].sdf, first)) {
      const Dims& a = first.dims();
      const Dims& b = surfaces[s].sdf.dims();
      std::ostringstream m;
      m << what << ": its grid (" << b.nx << "x" << b.ny << "x" << b.nz << ") differs from surface 1's (" << a.nx
        << "x" << a.ny << "x" << a.nz << ", or origin/spacing); expected every distance volume on one grid";
      throw InputError(m.str());
    }
    // Nodes within the band and the reconstruction's taps around them (two
    // voxels) read the distances: they must be exact there (see exact_within).
    for (const bool positive : {true, false}) {
      const double exact = exact_within(surfaces[s].sdf, positive, what), need = band + 2 * hmax;
      if (need > exact)
        throw InputError(what + ": its distances " + (positive ? "outside" : "inside") +
                         " the surface are exact only within " + format_number(exact) +
                         " of it (tighten --outside-band), but a band of " + format_number(p.band) +
                         " voxels reads them up to " + format_number(need) +
                         " (world units); expected a smaller --band or a wider --outside-band");
    }
  }
  SizingFieldResult res;
  res.h = Volume(VoxelType::f32, n, g);
  res.lfs = Volume(VoxelType::f32, n, g);
  float* H = res.h.data<float>();
  float* L = res.lfs.data<float>();
  std::vector<std::uint8_t> curv(n.count(), 0);

  for (const SizingSurface& surf : surfaces) {
    const VolumeField field(surf.sdf, VolumeFieldParams::chapter5_mix());
    const std::vector<float> d = surf.sdf.to_float();
    const KdTree tree(surf.medial_axis);
    pm::parallel_for(std::size_t(0), n.nz, [&](std::size_t k) {
      std::size_t last = std::size_t(-1);  // the previous query's nearest point: an upper bound
      for (std::size_t j = 0; j < n.ny; ++j)
        for (std::size_t i = 0; i < n.nx; ++i) {
          const std::size_t c = i + n.nx * (j + n.ny * k);
          const double dc = d[c];
          if (!(std::fabs(dc) <= band)) continue;
          Vec3 x = g.index_to_world(Vec3(double(i), double(j), double(k)));
          Vec3 grad;
          Mat3 hess;
          if (p.at_foot_point) {
            field.value_gradient(x, grad);
            const double gl = norm(grad);
            if (gl > 1e-9) {
              x = x - dc * grad / gl;
              const double f = field.value_gradient(x, grad);
              const double g2 = norm2(grad);
              if (g2 > 1e-18) x = x - f * grad / g2;
            }
          }
          field.evaluate(x, grad, hess);
          const Curvature cv = curvature(grad, hess);
          const double kmax = std::max(std::fabs(cv.k1), std::fabs(cv.k2));
          const double bound2 = last < tree.size() ? norm2(tree.point(last) - x) : 1e300;
          const double lfs = std::sqrt(tree.nearest2(x, last, bound2));
          const bool by_curv = kmax * lfs > 1;
          double h = C * (by_curv ? 1 / kmax : lfs);
          bool raised = false;
          if (h < p.hmin) {
            h = p.hmin;
            raised = true;
          }
          h = std::max(h, floor);
          if (H[c] == 0 || h < H[c]) {
            H[c] = float(h);
            curv[c] = std::uint8_t((by_curv ? 1 : 0) | (raised ? 2 : 0));
          }
          if (L[c] == 0 || lfs < L[c]) L[c] = float(std::max(lfs, floor));
        }
    });
  }

  bool first_known = true;
  for (std::size_t c = 0; c < n.count(); ++c) {
    if (H[c] == 0) continue;
    res.known++;
    res.curvature_limited += curv[c] & 1;
    res.hmin_limited += (curv[c] >> 1) & 1;
    if (first_known) {
      res.h_lo = res.h_hi = H[c];
      res.lfs_lo = res.lfs_hi = L[c];
      first_known = false;
    }
    res.h_lo = std::min(res.h_lo, double(H[c]));
    res.h_hi = std::max(res.h_hi, double(H[c]));
    res.lfs_lo = std::min(res.lfs_lo, double(L[c]));
    res.lfs_hi = std::max(res.lfs_hi, double(L[c]));
  }
  return res;
}

}  // namespace pm
