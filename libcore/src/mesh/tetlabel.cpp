#include "pm/mesh/tetlabel.h"

#include <tetgen.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <numeric>
#include <sstream>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/parallel.h"
#include "delaunay_cgal.h"

namespace pm {
namespace {

double signed_volume6(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return dot(b - a, cross(c - a, d - a));
}

// Outward faces of a positively oriented tetrahedron, face i opposite corner i.
constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

// At least 4 finite points spanning a volume (TetGen asserts, i.e. aborts,
// on a flat bounding box): refuse degenerate input here.
void require_volume_spanning(const std::vector<Vec3>& points) {
  if (points.size() < 4)
    throw InputError("delaunay: " + std::to_string(points.size()) + " points; expected at least 4");
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!is_finite(points[i])) throw InputError("delaunay: point " + std::to_string(i) + " is not finite");
  const Vec3& p0 = points[0];
  std::size_t i1 = 0, i2 = 0, i3 = 0;
  double best = 0;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (norm2(points[i] - p0) > best) best = norm2(points[i] - p0), i1 = i;
  const double scale = std::sqrt(best);
  const Vec3 dir = normalized(points[i1] - p0);
  best = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 q = points[i] - p0;
    const double d = norm2(q - dir * dot(q, dir));
    if (d > best) best = d, i2 = i;
  }
  const Vec3 nrm = normalized(cross(points[i1] - p0, points[i2] - p0));
  best = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double d = std::fabs(dot(points[i] - p0, nrm));
    if (d > best) best = d, i3 = i;
  }
  (void)i3;
  if (!(scale > 0) || !(best > 1e-12 * scale))
    throw InputError("delaunay: all " + std::to_string(points.size()) +
                     " points are coplanar (or coincide); expected points spanning a volume");
}

}  // namespace

std::string tetgen_failure(int code) {
  static const char* what[] = {"", "out of memory", "internal error", "self-intersection in input",
                               "small feature in input", "close facets in input", "self-intersection",
                               "input points are too close"};
  return code > 0 && code < 8 ? what[code] : "";
}

TetMesh delaunay(const std::vector<Vec3>& points) {
  require_volume_spanning(points);
  TetMesh tm;
  std::size_t distinct = 0;
  if (parallel_delaunay(points, tm, distinct)) {
    if (distinct != points.size())
      throw InputError("delaunay: " + std::to_string(points.size() - distinct) + " of " +
                       std::to_string(points.size()) + " points coincide with others; expected distinct points");
    if (tm.tets.empty())
      throw InputError("delaunay: no tetrahedra from " + std::to_string(points.size()) +
                       " points; expected points that are not all coplanar");
    return tm;
  }
  return tetgen_delaunay(points);
}

TetMesh tetgen_delaunay(const std::vector<Vec3>& points) {
  require_volume_spanning(points);
  tetgenio in, out;
  in.numberofpoints = int(points.size());
  in.pointlist = new REAL[points.size() * 3];
  for (std::size_t i = 0; i < points.size(); ++i) {
    in.pointlist[3 * i] = points[i].x;
    in.pointlist[3 * i + 1] = points[i].y;
    in.pointlist[3 * i + 2] = points[i].z;
  }
  char switches[] = "zQn";
  try {
    tetrahedralize(switches, &in, &out);
  } catch (int code) {
    std::ostringstream m;
    m << "delaunay: TetGen failed with code " << code;
    if (!tetgen_failure(code).empty()) m << " (" << tetgen_failure(code) << ")";
    m << " on " << points.size() << " points";
    throw InputError(m.str());
  }
  if (out.numberoftetrahedra <= 0)
    throw InputError("delaunay: TetGen made no tetrahedra from " + std::to_string(points.size()) +
                     " points; expected points that are not all coplanar");
  if (out.numberofpoints != int(points.size()))
    throw InputError("delaunay: TetGen returned " + std::to_string(out.numberofpoints) + " of " +
                     std::to_string(points.size()) + " points (duplicates?); expected distinct points");
  TetMesh tm;
  tm.points = points;
  const std::size_t nt = std::size_t(out.numberoftetrahedra);
  tm.tets.resize(nt);
  tm.neighbours.resize(nt);
  for (std::size_t t = 0; t < nt; ++t) {
    std::array<int, 4> v{}, n{};
    for (int i = 0; i < 4; ++i) {
      v[i] = out.tetrahedronlist[4 * t + i];
      n[i] = out.neighborlist[4 * t + i];
    }
    if (signed_volume6(points[v[0]], points[v[1]], points[v[2]], points[v[3]]) < 0) {
      std::swap(v[0], v[1]);
      std::swap(n[0], n[1]);
    }
    tm.tets[t] = v;
    tm.neighbours[t] = n;
  }
  return tm;
}

TetMesh delaunay_enclosed(const std::vector<Vec3>& points) {
  require_volume_spanning(points);
  std::vector<Vec3> all = points;
  Box bb;
  for (const Vec3& x : points) bb.extend(x);
  const double pad = norm(bb.size()) + 1.0;
  for (int c = 0; c < 8; ++c)
    all.push_back({c & 1 ? bb.hi.x + pad : bb.lo.x - pad, c & 2 ? bb.hi.y + pad : bb.lo.y - pad,
                   c & 4 ? bb.hi.z + pad : bb.lo.z - pad});
  TetMesh full = delaunay(all);
  const int n = int(points.size());
  std::vector<int> keep_index(full.tets.size(), -1);
  TetMesh tm;
  tm.points = points;
  for (std::size_t t = 0; t < full.tets.size(); ++t) {
    const auto& v = full.tets[t];
    if (v[0] < n && v[1] < n && v[2] < n && v[3] < n) {
      keep_index[t] = int(tm.tets.size());
      tm.tets.push_back(v);
    }
  }
  tm.neighbours.reserve(tm.tets.size());
  for (std::size_t t = 0; t < full.tets.size(); ++t) {
    if (keep_index[t] < 0) continue;
    std::array<int, 4> nb = full.neighbours[t];
    for (int& q : nb) q = q >= 0 ? keep_index[std::size_t(q)] : -1;
    tm.neighbours.push_back(nb);
  }
  return tm;
}

TetLabelStats label_tets(TetMesh& tm, const LabelFunction& label, const TetLabelParams& p) {
  TetLabelStats st;
  const std::size_t nt = tm.tets.size();
  st.tets = nt;
  constexpr int kUnset = std::numeric_limits<int>::min();
  tm.labels.assign(nt, kUnset);
  std::vector<Vec3> centroid(nt);
  // Every tetrahedron on its own (the label function is called side by side).
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, nt, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t t = r.begin(); t != r.end(); ++t) {
      const Vec3& a = tm.points[tm.tets[t][0]];
      const Vec3& b = tm.points[tm.tets[t][1]];
      const Vec3& c = tm.points[tm.tets[t][2]];
      const Vec3& d = tm.points[tm.tets[t][3]];
      const Vec3 u = b - a, v = c - a, w = d - a;
      const double vol6 = dot(u, cross(v, w));
      const double lrms =
          std::sqrt((norm2(u) + norm2(v) + norm2(w) + norm2(b - c) + norm2(b - d) + norm2(c - d)) / 6.0);
      // Regular tetrahedron: V = l³/(6√2), so √2·(6V)/l³ = 1.
      const double quality = std::sqrt(2.0) * vol6 / (lrms * lrms * lrms);
      centroid[t] = a + (u + v + w) * 0.25;
      if (quality >= p.flat_quality && vol6 > 0) {
        const Vec3 cc = a + (norm2(u) * cross(v, w) + norm2(v) * cross(w, u) + norm2(w) * cross(u, v)) / (2.0 * vol6);
        tm.labels[t] = label(cc);
      }
    }
  });
  // Flat tetrahedra come from (nearly) co-spherical points: in exact arithmetic
  // they share the circumsphere of the cluster they belong to, so they take
  // the label of their labelled face neighbours (majority; a tie, e.g. a lone
  // flat tetrahedron lying on the surface, is decided at the centroid).
  // Breadth-first from the labelled tetrahedra, in index order: deterministic.
  std::vector<std::size_t> frontier, next;
  for (std::size_t t = 0; t < nt; ++t)
    if (tm.labels[t] == kUnset) frontier.push_back(t);
  st.flat = frontier.size();
  while (!frontier.empty()) {
    next.clear();
    std::vector<std::pair<std::size_t, int>> decided;
    for (std::size_t t : frontier) {
      int votes[4], nv = 0;
      for (int n : tm.neighbours[t])
        if (n >= 0 && tm.labels[n] != kUnset) votes[nv++] = tm.labels[n];
      if (nv == 0) {
        next.push_back(t);
        continue;
      }
      int best = kUnset, best_count = 0;
      bool tie = false;
      for (int i = 0; i < nv; ++i) {
        int c = 0;
        for (int j = 0; j < nv; ++j) c += votes[j] == votes[i];
        if (c > best_count) {
          best = votes[i];
          best_count = c;
          tie = false;
        } else if (c == best_count && votes[i] != best) {
          tie = true;
        }
      }
      decided.emplace_back(t, tie ? label(centroid[t]) : best);
    }
    if (decided.empty()) {  // islands of flat tetrahedra with no labelled neighbour
      for (std::size_t t : next) tm.labels[t] = label(centroid[t]);
      break;
    }
    for (const auto& [t, l] : decided) tm.labels[t] = l;
    frontier.swap(next);
  }
  return st;
}

namespace {
// Visit every face between two differently labelled tetrahedra once (hull
// faces border `outside_label`). `orient(back, front)` returns +1 to keep the
// face with its normal from the back label into the front label, -1 to keep
// it flipped, 0 to skip it.
Mesh collect_faces(const TetMesh& tm, int outside_label, const std::function<int(int, int)>& orient,
                   bool with_labels) {
  Mesh m;
  std::vector<int> remap(tm.points.size(), -1);
  std::vector<double>& index = m.vertex_scalars["index"];
  auto vid = [&](int p) {
    if (remap[p] < 0) {
      remap[p] = int(m.vertices.size());
      m.vertices.push_back(tm.points[p]);
      index.push_back(double(p));
    }
    return remap[p];
  };
  std::vector<int> la, lb;
  for (std::size_t t = 0; t < tm.tets.size(); ++t) {
    const int l = tm.labels[t];
    for (int i = 0; i < 4; ++i) {
      const int n = tm.neighbours[t][i];
      if (n >= 0 && std::size_t(n) < t) continue;  // seen from the other side already
      const int ln = n < 0 ? outside_label : tm.labels[n];
      if (ln == l) continue;
      const int o = orient(l, ln);
      if (o == 0) continue;
      const auto& v = tm.tets[t];
      // Outward face of tet t: normal points from l (back) into ln (front).
      if (o > 0) {
        m.faces.push_back({vid(v[kFace[i][0]]), vid(v[kFace[i][1]]), vid(v[kFace[i][2]])});
        la.push_back(l);
        lb.push_back(ln);
      } else {
        m.faces.push_back({vid(v[kFace[i][0]]), vid(v[kFace[i][2]]), vid(v[kFace[i][1]])});
        la.push_back(ln);
        lb.push_back(l);
      }
    }
  }
  if (with_labels) {
    m.face_ints["label_a"] = std::move(la);
    m.face_ints["label_b"] = std::move(lb);
  }
  return m;
}
}  // namespace

Mesh interface_mesh(const TetMesh& tm, int outside_label) {
  if (tm.labels.size() != tm.tets.size()) throw Error("interface_mesh: tetrahedra are not labelled");
  return collect_faces(tm, outside_label, [](int l, int ln) { return l < ln ? 1 : -1; }, true);
}

Mesh material_surface(const TetMesh& tm, int label, int outside_label) {
  if (tm.labels.size() != tm.tets.size()) throw Error("material_surface: tetrahedra are not labelled");
  return collect_faces(
      tm, outside_label, [label](int l, int ln) { return l == label ? 1 : (ln == label ? -1 : 0); }, false);
}

VertexTets::VertexTets(const TetMesh& tm) : start(tm.points.size() + 1, 0) {
  for (const auto& t : tm.tets)
    for (int v : t) ++start[std::size_t(v) + 1];
  for (std::size_t v = 0; v < tm.points.size(); ++v) start[v + 1] += start[v];
  tets.resize(start.back());
  std::vector<int> at(start.begin(), start.end() - 1);
  for (std::size_t i = 0; i < tm.tets.size(); ++i)
    for (int v : tm.tets[i]) tets[std::size_t(at[std::size_t(v)]++)] = int(i);
}

namespace {
struct ManifoldChecker {
  const TetMesh& tm;
  int label, outside;
  VertexTets vt;
  // Scratch of ok(): the link edges, the link vertices and their two
  // neighbours (the link of a vertex is small: tens of edges).
  mutable std::vector<std::pair<int, int>> edges;
  mutable std::vector<int> verts;
  mutable std::vector<std::array<int, 3>> adj;  // neighbour, neighbour, degree

  ManifoldChecker(const TetMesh& t, int l, int o) : tm(t), label(l), outside(o), vt(t) {}
  bool member(int t) const { return t >= 0 && tm.labels[t] == label; }
  // True when the material's faces at v form one closed fan (or none): every
  // vertex of its link has two link edges, and the link is one cycle.
  bool ok(int v) const {
    edges.clear();  // the two other vertices of each face at v
    for (const int* it = vt.begin(v); it != vt.end(v); ++it) {
      const int t = *it;
      if (!member(t)) continue;
      const auto& tv = tm.tets[t];
      for (int i = 0; i < 4; ++i) {
        if (tv[i] == v) continue;
        if (member(tm.neighbours[t][i])) continue;
        int a = -1, b = -1;
        for (int k = 0; k < 3; ++k) {
          const int w = tv[kFace[i][k]];
          if (w == v) continue;
          (a < 0 ? a : b) = w;
        }
        edges.emplace_back(a, b);
      }
    }
    if (edges.empty()) return true;
    verts.clear();
    adj.clear();
    auto slot = [&](int w) {
      for (std::size_t k = 0; k < verts.size(); ++k)
        if (verts[k] == w) return k;
      verts.push_back(w);
      adj.push_back({-1, -1, 0});
      return verts.size() - 1;
    };
    for (const auto& [a, b] : edges) {
      const std::size_t sa = slot(a), sb = slot(b);
      for (auto [s, o] : {std::pair<std::size_t, int>{sa, int(sb)}, {sb, int(sa)}}) {
        std::array<int, 3>& n = adj[s];
        if (n[2] < 2) n[std::size_t(n[2])] = o;
        ++n[2];
      }
    }
    for (const auto& n : adj)
      if (n[2] != 2) return false;
    // One cycle: walk it.
    std::size_t steps = 0;
    int prev = -1, cur = int(slot(edges[0].first));
    const int start = cur;
    do {
      const auto& n = adj[std::size_t(cur)];
      const int next = n[0] != prev ? n[0] : n[1];
      prev = cur;
      cur = next;
      ++steps;
    } while (cur != start && steps <= edges.size());
    return steps == edges.size();
  }
  bool ok_around(int t) const {
    for (int v : tm.tets[t])
      if (!ok(v)) return false;
    return true;
  }
};

int other_label(const TetMesh& tm, int t, int label, int outside) {
  int votes[4], n = 0;
  for (int nb : tm.neighbours[t]) {
    const int l = nb < 0 ? outside : tm.labels[nb];
    if (l != label) votes[n++] = l;
  }
  if (n == 0) return outside;
  int best = votes[0], best_count = 0;
  for (int i = 0; i < n; ++i) {
    int c = 0;
    for (int j = 0; j < n; ++j) c += votes[j] == votes[i];
    if (c > best_count || (c == best_count && votes[i] < best)) best = votes[i], best_count = c;
  }
  return best;
}
}  // namespace

std::size_t make_manifold(TetMesh& tm, int label, int outside_label) {
  if (tm.labels.size() != tm.tets.size()) throw Error("make_manifold: tetrahedra are not labelled");
  ManifoldChecker mc(tm, label, outside_label);
  std::size_t flips = 0;
  for (int round = 0; round < 4; ++round) {
    std::vector<int> bad;
    for (std::size_t v = 0; v < tm.points.size(); ++v)
      if (!mc.vt.empty(int(v)) && !mc.ok(int(v))) bad.push_back(int(v));
    if (bad.empty()) break;
    for (int v : bad) {
      if (mc.ok(v)) continue;
      bool fixed = false;
      for (const int* it = mc.vt.begin(v); it != mc.vt.end(v); ++it) {
        const int t = *it;
        const int old = tm.labels[t];
        tm.labels[t] = old == label ? other_label(tm, t, label, outside_label) : label;
        if (mc.ok_around(t)) {
          fixed = true;
          ++flips;
          break;
        }
        tm.labels[t] = old;
      }
      if (fixed) continue;
      for (const int* it = mc.vt.begin(v); it != mc.vt.end(v); ++it)
        if (const int t = *it; tm.labels[t] != label) {
          tm.labels[t] = label;
          ++flips;
        }
    }
  }
  return flips;
}

LabelledTets labelled_tets(const TetMesh& tm, int outside_label) {
  LabelledTets out;
  std::vector<int> remap(tm.points.size(), -1);
  for (std::size_t t = 0; t < tm.tets.size(); ++t) {
    if (tm.labels[t] == outside_label) continue;
    std::array<int, 4> c;
    for (int k = 0; k < 4; ++k) {
      int& r = remap[std::size_t(tm.tets[t][k])];
      if (r < 0) {
        r = int(out.vertices.size());
        out.vertices.push_back(tm.points[std::size_t(tm.tets[t][k])]);
      }
      c[k] = r;
    }
    out.tets.push_back(c);
    out.materials.push_back(tm.labels[t]);
  }
  const Mesh im = interface_mesh(tm, outside_label);
  const auto& index = im.vertex_scalars.at("index");
  const auto& la = im.face_ints.at("label_a");
  const auto& lb = im.face_ints.at("label_b");
  for (std::size_t f = 0; f < im.faces.size(); ++f) {
    std::array<int, 3> c;
    for (int k = 0; k < 3; ++k) c[k] = remap[std::size_t(index[std::size_t(im.faces[f][k])])];
    // Every such face borders a kept tetrahedron, so its corners are kept.
    out.triangles.push_back(c);
    out.triangle_labels.push_back({la[f], lb[f]});
  }
  return out;
}

}  // namespace pm
