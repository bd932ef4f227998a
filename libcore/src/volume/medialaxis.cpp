#include "pm/volume/medialaxis.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>

#include "pm/base/error.h"
#include "pm/base/parallel.h"
#include "pm/field/volume_field.h"

namespace pm {

void require_distance_volume(const Volume& v, const std::string& what) {
  if (is_integer(v.type())) {
    std::ostringstream m;
    m << what << ": expected a signed distance volume (float), got a " << voxel_type_name(v.type()) << " "
      << (value_range(v).hi - value_range(v).lo <= 1 ? "mask" : "label map or integer volume");
    throw InputError(m.str());
  }
  require_finite(v, what);
  double a = v.get(0), b = a;
  bool more = false;
  for (std::size_t c = 1; c < v.count() && !more; ++c) {
    const double x = v.get(c);
    if (x == a || x == b) continue;
    if (a == b) b = x;
    else more = true;
  }
  if (!more) {
    std::ostringstream m;
    m << what << ": expected a signed distance volume (float), got a " << voxel_type_name(v.type())
      << " volume with only " << (a == b ? 1 : 2) << " value" << (a == b ? "" : "s") << " (a mask?)";
    throw InputError(m.str());
  }
  const ValueRange r = value_range(v);
  if (!(r.lo < 0 && r.hi >= 0)) {
    std::ostringstream m;
    m << what << ": no zero crossing (values from " << r.lo << " to " << r.hi
      << "); expected a signed distance volume, negative inside";
    throw InputError(m.str());
  }
}

namespace {

// medial_axis_lfs_bound keeps MA points up to this many times the depth of
// the shallower side. In theory once is enough (see the header), but
// sizingfield measures LFS at a node's closest surface point as estimated
// from the distance field, which near the MA can lie voxels off the surface;
// once changed 6 of 348k frog nodes, twice none there or on the brain.
constexpr double kLfsBoundDepths = 2.0;

struct MaPoint {
  Vec3 x;
  double distance;
  bool inner;
};

}  // namespace

MedialAxisResult medial_axis(const Volume& sdf, const MedialAxisParams& p) {
  if (!(p.cos_alpha > -1 && p.cos_alpha < 1))
    throw UsageError("medial_axis: cos_alpha " + std::to_string(p.cos_alpha) + " is invalid; expected in (-1, 1)");
  if (p.foot_iterations < 0) throw UsageError("medial_axis: foot_iterations must be >= 0");
  if (!(p.max_distance > 0))
    throw UsageError("medial_axis: max_distance " + std::to_string(p.max_distance) + " is invalid; expected > 0 (world units)");
  require_distance_volume(sdf, "medial_axis: input");
  const Geometry& g = sdf.geometry();
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b)
      if (!(std::fabs(dot(g.directions.column(a), g.directions.column(b))) < 1e-6 * g.spacing(a) * g.spacing(b)))
        throw InputError("medial_axis: axes " + std::to_string(a) + " and " + std::to_string(b) +
                         " are not orthogonal; expected an orthogonal direction matrix");

  const VolumeField field(sdf, VolumeFieldParams::chapter5_mix());
  const std::vector<float> d = sdf.to_float();
  const Dims& n = sdf.dims();
  const std::size_t nx = n.nx, ny = n.ny, nz = n.nz, sy = nx, sz = nx * ny;
  const double h[3] = {g.spacing(0), g.spacing(1), g.spacing(2)};
  const Vec3 e[3] = {g.directions.column(0) / h[0], g.directions.column(1) / h[1], g.directions.column(2) / h[2]};
  const double hmin = std::min(h[0], std::min(h[1], h[2]));
  // Nodes tested (|d| <= max_distance) read the feet of nodes up to about two
  // voxel diagonals away, and those (pass 2) their neighbours' feet: feet are
  // found within three diagonals more (|d| is 1-Lipschitz), so every tested
  // node sees what it would see on the whole grid.
  const double diag = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
  const double test_d = p.max_distance, fill_d = test_d + 2.5 * diag, foot_d = test_d + 3.5 * diag;
  // With one side only, the other side's nodes are needed just as far as a
  // tested node reads (the same 2.5 and 3.5 diagonals, now from the surface):
  // the points found are the same, and a material's outer side (mostly the
  // whole rest of the volume) costs nothing.
  const double foot_lo = p.inside ? -foot_d : -3.5 * diag, foot_hi = p.outside ? foot_d : 3.5 * diag;
  const double fill_lo = p.inside ? -fill_d : -2.5 * diag, fill_hi = p.outside ? fill_d : 2.5 * diag;
  // Those nodes' values, and their neighbours' (central differences), must be
  // exact: a distance that is exact only near its surface on one side
  // (tighten --outside-band) is refused where this would read farther.
  const double hmax = std::max(h[0], std::max(h[1], h[2]));
  const std::string side = p.inside && p.outside ? "both" : p.inside ? "inside" : "outside";
  for (const bool positive : {true, false}) {
    const double need = (positive ? foot_hi : -foot_lo) + hmax, exact = exact_within(sdf, positive, "medial_axis: input");
    if (need > exact)
      throw InputError("medial_axis: input: its distances " + std::string(positive ? "outside" : "inside") +
                       " the surface are exact only within " + format_number(exact) +
                       " of it (tighten --outside-band), but --side " + side + " reads them " +
                       (std::isfinite(need) ? "up to " + format_number(need) + " (world units)" : "everywhere") +
                       "; expected --side " + (positive ? "inside" : "outside") +
                       " with a band of at least " + format_number(3.5 * diag + hmax) +
                       " (tighten --outside-band auto), or a distance without --outside-band");
  }
  const Vec3 ex = e[0] / (2 * h[0]), ey = e[1] / (2 * h[1]), ez = e[2] / (2 * h[2]);  // central differences

  // Foot point of x from the guess p = x - f n0 (f: value at x, n0: unit
  // normal guess), refined by Newton steps for "x - p is normal to the
  // surface at p": project p onto the surface, take the tangential residual
  // r of x - p, and move p by (I + s S)^-1 r in the tangent plane (S: shape
  // operator at p, s: signed distance of x along the normal). The plain
  // fixed-point step (move by r) converges at rate |s| κ, which is slow just
  // where it matters: near the medial axis |s| κ -> 1. Fails where the field
  // is not distance-like at p (|grad| < 0.5) or the steps do not settle.
  struct Foot {
    Vec3 p, u;     // foot point; unit direction from p towards x
    double s = 0;  // |x - p|
    bool ok = false;
  };
  auto refine = [&](const Vec3& x, double f, const Vec3& n0) {
    Foot r;
    Vec3 pt = x - f * n0, nn = n0, gr;
    Mat3 H;
    double s = f, res = 1e300;
    for (int it = 0; it <= p.foot_iterations; ++it) {
      // The last iteration only measures the residual: no Hessian (the value
      // and gradient are the same either way).
      const double fp = it == p.foot_iterations ? field.value_gradient(pt, gr) : field.evaluate(pt, gr, H);
      const double gl = norm(gr);
      if (!(gl > 0.5)) return r;
      nn = gr / gl;
      pt = pt - (fp / gl) * nn;
      const Vec3 v = x - pt;
      s = dot(nn, v);
      const Vec3 rt = v - s * nn;
      res = norm(rt);
      if (res < 0.01 * hmin || it == p.foot_iterations) break;
      // Tangent basis and the shape operator S = P H P / |grad| in it.
      const Vec3 helper = std::fabs(nn.x) < 0.6 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
      const Vec3 t1 = normalized(cross(nn, helper)), t2 = cross(nn, t1);
      const double s11 = dot(t1, H * t1) / gl, s12 = dot(t1, H * t2) / gl, s22 = dot(t2, H * t2) / gl;
      const double a11 = 1 + s * s11, a12 = s * s12, a22 = 1 + s * s22;
      const double det = a11 * a22 - a12 * a12;
      const double r1 = dot(rt, t1), r2 = dot(rt, t2);
      Vec3 step = rt;  // fixed-point step where Newton's system is near singular
      if (std::fabs(det) > 0.05) step = ((a22 * r1 - a12 * r2) / det) * t1 + ((a11 * r2 - a12 * r1) / det) * t2;
      const double len = norm(step), cap = 2 * hmin + res;
      if (len > cap) step = step * (cap / len);
      pt = pt + step;
    }
    if (!(res < 0.1 * hmin)) return r;
    r.p = pt;
    r.u = (s > 0 || (s == 0 && f >= 0)) ? nn : -nn;
    r.s = std::fabs(s);
    r.ok = true;
    return r;
  };
  // Central-difference gradient of the grid at node (i,j,k), one-sided at the border.
  auto cd = [&](std::size_t i, std::size_t j, std::size_t k) {
    const std::size_t c = i + sy * j + sz * k;
    if (i > 0 && j > 0 && k > 0 && i + 1 < nx && j + 1 < ny && k + 1 < nz)
      return (d[c + 1] - d[c - 1]) * ex + (d[c + sy] - d[c - sy]) * ey + (d[c + sz] - d[c - sz]) * ez;
    const std::size_t ijk[3] = {i, j, k}, st[3] = {1, sy, sz}, len[3] = {nx, ny, nz};
    double v[3];
    for (int a = 0; a < 3; ++a) {
      const std::size_t lo = ijk[a] > 0 ? c - st[a] : c, hi = ijk[a] + 1 < len[a] ? c + st[a] : c;
      const double span = double((ijk[a] > 0) + (ijk[a] + 1 < len[a])) * h[a];
      v[a] = span > 0 ? (d[hi] - d[lo]) / span : 0.0;
    }
    return v[0] * e[0] + v[1] * e[1] + v[2] * e[2];  // world frame
  };
  // The closest of the foot points reached from the reconstructed gradient at
  // x and from the grid gradients of nearby nodes. Near the MA the smoothed
  // gradient at x averages both sides and leads astray; the neighbours'
  // gradients lead to both sides, and the closer foot point is the foot
  // point. `dref` (>= 0) is the known distance of x: a candidate agreeing
  // with it is accepted at once, and the result must agree with it.
  auto best_foot = [&](const Vec3& x, double f, const Vec3& gx, double dref, const Vec3* dirs, int nd) {
    Foot best;
    const double gl = norm(gx);
    if (gl > 1e-9) {
      best = refine(x, f, gx / gl);
      if (best.ok && std::fabs(best.s - (dref >= 0 ? dref : std::fabs(f))) < 0.1 * hmin) return best;
    }
    for (int t = 0; t < nd; ++t) {
      const double l = norm(dirs[t]);
      if (!(l > 0.5)) continue;
      const Foot c = refine(x, f, dirs[t] / l);
      if (c.ok && (!best.ok || c.s < best.s)) best = c;
    }
    if (best.ok && dref >= 0 && std::fabs(best.s - dref) > 0.25 * hmin) best.ok = false;
    return best;
  };

  const std::size_t N = n.count();
  const Mat3 to_index = inverse(g.directions);
  const Vec3 D[3] = {g.directions.column(0), g.directions.column(1), g.directions.column(2)};
  // Pass 1: the foot point of every node, stored as an offset from the node.
  // Where the grid gradients of the node and its six neighbours agree (no
  // medial axis within a voxel), the foot is q - d(q) g/|g| with the grid
  // gradient g; elsewhere it is found on the reconstructed field (best_foot).
  // Read only where ok[] says it was written: not zero-filled (51 MB on a frog material).
  const std::unique_ptr<std::array<float, 3>[]> off(new std::array<float, 3>[N]);
  std::vector<std::uint8_t> ok(N, 0);
  std::vector<std::size_t> tested(nz, 0);
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    for (std::size_t j = 0; j < ny; ++j)
      for (std::size_t i = 0; i < nx; ++i) {
        const std::size_t c = i + sy * j + sz * k;
        const double dq = d[c];
        if (!(dq >= foot_lo && dq <= foot_hi)) continue;
        const Vec3 g0 = cd(i, j, k);
        const double l0 = norm(g0);
        Vec3 dirs[6];
        int nd = 0;
        if (i > 0) dirs[nd++] = cd(i - 1, j, k);
        if (i + 1 < nx) dirs[nd++] = cd(i + 1, j, k);
        if (j > 0) dirs[nd++] = cd(i, j - 1, k);
        if (j + 1 < ny) dirs[nd++] = cd(i, j + 1, k);
        if (k > 0) dirs[nd++] = cd(i, j, k - 1);
        if (k + 1 < nz) dirs[nd++] = cd(i, j, k + 1);
        bool simple = l0 > 0.9 && l0 < 1.1;
        for (int t = 0; t < nd && simple; ++t) {
          const double l1 = norm(dirs[t]);
          simple = l1 > 0.9 && dot(g0, dirs[t]) > 0.99 * l0 * l1;
        }
        Vec3 o;
        if (simple) {
          o = (-dq / l0) * g0;
        } else {
          ++tested[k];
          const Vec3 q = g.index_to_world(Vec3(double(i), double(j), double(k)));
          Vec3 gq;
          field.value_gradient(q, gq);
          const Foot f = best_foot(q, dq, gq, std::fabs(dq), dirs, nd);
          if (!f.ok) continue;
          o = f.p - q;
        }
        off[c] = {float(o.x), float(o.y), float(o.z)};
        ok[c] = 1;
      }
  });
  // Pass 2: nodes without a foot take the closest of their neighbours' feet
  // that agrees with their own distance.
  std::vector<std::uint8_t> ok2 = ok;
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    for (std::size_t j = 0; j < ny; ++j)
      for (std::size_t i = 0; i < nx; ++i) {
        const std::size_t c = i + sy * j + sz * k;
        if (ok[c] || !(d[c] >= fill_lo && d[c] <= fill_hi)) continue;
        const Vec3 q = g.index_to_world(Vec3(double(i), double(j), double(k)));
        double best = 1e300;
        Vec3 bp;
        for (std::size_t kk = k > 0 ? k - 1 : 0; kk <= std::min(k + 1, nz - 1); ++kk)
          for (std::size_t jj = j > 0 ? j - 1 : 0; jj <= std::min(j + 1, ny - 1); ++jj)
            for (std::size_t ii = i > 0 ? i - 1 : 0; ii <= std::min(i + 1, nx - 1); ++ii) {
              const std::size_t b = ii + sy * jj + sz * kk;
              if (!ok[b]) continue;
              const Vec3 pb = g.index_to_world(Vec3(double(ii), double(jj), double(kk))) +
                              Vec3(off[b][0], off[b][1], off[b][2]);
              const double dist = norm(q - pb);
              if (dist < best) {
                best = dist;
                bp = pb;
              }
            }
        if (best < 1e300 && std::fabs(best - std::fabs(d[c])) < 0.25 * hmin) {
          const Vec3 o = bp - q;
          off[c] = {float(o.x), float(o.y), float(o.z)};
          ok2[c] = 1;
        }
      }
  });
  ok.swap(ok2);

  // Pass 3: the test. From q along its characteristic u to the far face of
  // its voxel, q2; q2's foot point is the closest of the feet of the corners
  // of q2's cell, and the characteristic there is that corner's (the surface
  // normal at its foot).
  std::vector<std::vector<MaPoint>> per(nz);
  pm::parallel_for(std::size_t(0), nz, [&](std::size_t k) {
    for (std::size_t j = 0; j < ny; ++j)
      for (std::size_t i = 0; i < nx; ++i) {
        const std::size_t c = i + sy * j + sz * k;
        if (!ok[c]) continue;
        const double dq = d[c];
        if ((dq < 0 ? !p.inside : !p.outside) || !(std::fabs(dq) <= test_d)) continue;
        const Vec3 q = g.index_to_world(Vec3(double(i), double(j), double(k)));
        const Vec3 o(off[c][0], off[c][1], off[c][2]);
        const double s = norm(o);
        if (!(s > 1e-6 * hmin)) continue;  // on the surface
        const Vec3 u = -o / s;
        double t = 1e300;
        for (int a = 0; a < 3; ++a) {
          const double ua = std::fabs(dot(u, e[a]));
          if (ua > 1e-12) t = std::min(t, 0.5 * h[a] / ua);
        }
        const Vec3 q2 = q + t * u;
        const Vec3 t2 = to_index * (q2 - g.origin);
        if (!(t2.x >= 0 && t2.y >= 0 && t2.z >= 0 && t2.x <= double(nx - 1) && t2.y <= double(ny - 1) &&
              t2.z <= double(nz - 1)))
          continue;
        const std::size_t i0 = std::min(std::size_t(t2.x), nx - 2), j0 = std::min(std::size_t(t2.y), ny - 2),
                          k0 = std::min(std::size_t(t2.z), nz - 2);
        // Squared distances from q2 to the corners' feet, relative to corner 0.
        const Vec3 r0 = q2 - g.index_to_world(Vec3(double(i0), double(j0), double(k0)));
        double best = 1e300;
        std::size_t bb = 0;
        Vec3 ob;
        for (std::size_t dk = 0; dk < 2; ++dk)
          for (std::size_t dj = 0; dj < 2; ++dj)
            for (std::size_t di = 0; di < 2; ++di) {
              const std::size_t b = (i0 + di) + sy * (j0 + dj) + sz * (k0 + dk);
              if (!ok[b]) continue;
              const Vec3 o2(off[b][0], off[b][1], off[b][2]);
              const Vec3 v = r0 - double(di) * D[0] - double(dj) * D[1] - double(dk) * D[2] - o2;
              const double dist = norm2(v);
              if (dist < best) {
                best = dist;
                bb = b;
                ob = o2;
              }
            }
        const double sb = norm(ob);
        if (best == 1e300 || !(sb > 1e-6 * hmin)) continue;
        const Vec3 pf2 = g.index_to_world(Vec3(double(bb % nx), double((bb / nx) % ny), double(bb / sz))) + ob;
        const Vec3 u2 = -ob / sb;
        const double cu = dot(u, u2);
        if (!(cu < p.cos_alpha)) continue;
        // Where the tangent planes at p and p' are equidistant along q + x u.
        double x = (dot(q - pf2, u2) - s) / (1 - cu);
        x = std::min(std::max(x, 0.0), t);
        const Vec3 m = q + x * u;
        per[k].push_back({m, std::max(0.0, s + x), dq < 0});
      }
  });

  MedialAxisResult res;
  std::size_t total = 0;
  for (std::size_t k = 0; k < nz; ++k) {
    total += per[k].size();
    res.nodes_refined += tested[k];
  }
  res.points.vertices.reserve(total);
  std::vector<double>& dist = res.points.vertex_scalars["distance"];
  dist.reserve(total);
  for (const auto& v : per)
    for (const MaPoint& m : v) {
      res.points.vertices.push_back(m.x);
      dist.push_back(m.distance);
      (m.inner ? res.inner : res.outer)++;
    }
  return res;
}

double medial_axis_lfs_bound(const Volume& sdf) {
  const Dims& n = sdf.dims();
  const Geometry& g = sdf.geometry();
  const std::vector<float> d = sdf.to_float();
  double deep_in = 0, deep_out = 0;
  bool in_on_faces = false, out_on_faces = false;
  for (std::size_t k = 0; k < n.nz; ++k)
    for (std::size_t j = 0; j < n.ny; ++j)
      for (std::size_t i = 0; i < n.nx; ++i) {
        const double v = d[i + n.nx * (j + n.ny * k)];
        deep_in = std::max(deep_in, -v);
        deep_out = std::max(deep_out, v);
        if (i == 0 || j == 0 || k == 0 || i + 1 == n.nx || j + 1 == n.ny || k + 1 == n.nz) {
          in_on_faces = in_on_faces || v < 0;
          out_on_faces = out_on_faces || v > 0;
        }
      }
  double deep = HUGE_VAL;
  if (!in_on_faces) deep = std::min(deep, deep_in);
  if (!out_on_faces) deep = std::min(deep, deep_out);
  const double diag = std::sqrt(g.spacing(0) * g.spacing(0) + g.spacing(1) * g.spacing(1) + g.spacing(2) * g.spacing(2));
  return kLfsBoundDepths * deep + 2 * diag;
}

Volume mark_points(const Volume& like, const std::vector<Vec3>& points) {
  Volume out(VoxelType::u8, like.dims(), like.geometry());
  const Dims& n = like.dims();
  for (const Vec3& x : points) {
    const Vec3 t = like.geometry().world_to_index(x);
    const double i = std::round(t.x), j = std::round(t.y), k = std::round(t.z);
    if (i < 0 || j < 0 || k < 0 || i >= double(n.nx) || j >= double(n.ny) || k >= double(n.nz)) continue;
    out.set(std::size_t(i), std::size_t(j), std::size_t(k), 1);
  }
  return out;
}

}  // namespace pm
