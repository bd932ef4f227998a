#include "pm/mesh/tet_conform.h"

#include <tetgen.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/mesh/meshstats.h"
#include "pm/mesh/tet_smooth.h"
#include "pm/mesh/tetlabel.h"

namespace pm {
namespace {

std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
}

std::array<int, 3> sorted(std::array<int, 3> f) {
  std::sort(f.begin(), f.end());
  return f;
}

struct TriHash {
  std::size_t operator()(const std::array<int, 3>& f) const {
    std::uint64_t h = std::uint32_t(f[0]);
    h = h * 0x9E3779B97F4A7C15ULL ^ std::uint32_t(f[1]);
    h = h * 0x9E3779B97F4A7C15ULL ^ std::uint32_t(f[2]);
    return std::size_t(h ^ (h >> 29));
  }
};

// Exact coordinates as a key: TetGen copies input points bit for bit, so a
// point it returns is an input point exactly when its bits match.
struct PointKey {
  std::uint64_t b[3];
  bool operator==(const PointKey& o) const { return b[0] == o.b[0] && b[1] == o.b[1] && b[2] == o.b[2]; }
};
struct PointKeyHash {
  std::size_t operator()(const PointKey& k) const {
    std::uint64_t h = k.b[0];
    h = h * 0x9E3779B97F4A7C15ULL ^ k.b[1];
    h = h * 0x9E3779B97F4A7C15ULL ^ k.b[2];
    return std::size_t(h ^ (h >> 31));
  }
};
PointKey key_of(const double* x) {
  PointKey k;
  for (int i = 0; i < 3; ++i) {
    const double v = x[i] == 0 ? 0.0 : x[i];  // -0 == +0
    std::memcpy(&k.b[i], &v, sizeof v);
  }
  return k;
}

// Cubes of edge w for the two hashed grids below.
using Cell = std::array<long, 3>;
struct CellHash {
  std::size_t operator()(const Cell& c) const {
    return std::size_t((c[0] * 73856093L) ^ (c[1] * 19349663L) ^ (c[2] * 83492791L));
  }
};
Cell cell_of(const Vec3& x, double w) {
  return {long(std::floor(x.x / w)), long(std::floor(x.y / w)), long(std::floor(x.z / w))};
}

// Points by cell of side `h`, for "is any point within h of x?".
class PointGrid {
 public:
  explicit PointGrid(double h) : h_(h) {}
  void add(const Vec3& x) { cells_[cell(x)].push_back(x); }
  bool near(const Vec3& x) const {
    const auto c = cell(x);
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find({c[0] + dx, c[1] + dy, c[2] + dz});
          if (it == cells_.end()) continue;
          for (const Vec3& y : it->second)
            if (norm2(y - x) <= h_ * h_) return true;
        }
    return false;
  }

 private:
  Cell cell(const Vec3& x) const { return cell_of(x, h_); }
  double h_;
  std::unordered_map<Cell, std::vector<Vec3>, CellHash> cells_;
};

// Squared distance from x to triangle abc: the nearest point is inside the
// triangle (its plane) or on one of the three edges.
double triangle_distance2(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = cross(b - a, c - a);
  const double nn = norm2(n);
  if (nn > 0) {
    const double t = dot(x - a, n) / nn;
    const Vec3 q = x - n * t;  // projection onto the plane
    const bool in = dot(cross(b - a, q - a), n) >= 0 && dot(cross(c - b, q - b), n) >= 0 &&
                    dot(cross(a - c, q - c), n) >= 0;
    if (in) return t * t * nn;
  }
  auto seg = [&](const Vec3& p, const Vec3& q) {
    const Vec3 d = q - p;
    const double dd = norm2(d);
    const double s = dd > 0 ? std::clamp(dot(x - p, d) / dd, 0.0, 1.0) : 0.0;
    return norm2(x - (p + d * s));
  };
  return std::min({seg(a, b), seg(b, c), seg(c, a)});
}

// Triangles by the grid cells their bounding boxes (grown by h) overlap,
// for "is any triangle within h of x?".
class TriangleGrid {
 public:
  /// Points within h of a triangle, plus `relative` times the triangle's
  /// longest edge.
  TriangleGrid(const std::vector<Vec3>& v, const std::vector<std::array<int, 3>>& t, double cell, double h,
               double relative = 0)
      : v_(v), t_(t), cell_(cell), h_(t.size(), h) {
    for (std::size_t f = 0; f < t.size(); ++f) {
      Box bb;
      double longest = 0;
      for (int k = 0; k < 3; ++k) {
        bb.extend(v[std::size_t(t[f][k])]);
        longest = std::max(longest, norm(v[std::size_t(t[f][(k + 1) % 3])] - v[std::size_t(t[f][k])]));
      }
      const double hf = h_[f] += relative * longest;
      const auto lo = key(bb.lo - Vec3{hf, hf, hf}), hi = key(bb.hi + Vec3{hf, hf, hf});
      for (long i = lo[0]; i <= hi[0]; ++i)
        for (long j = lo[1]; j <= hi[1]; ++j)
          for (long k = lo[2]; k <= hi[2]; ++k) cells_[{i, j, k}].push_back(int(f));
    }
  }
  bool near(const Vec3& x) const {
    const auto it = cells_.find(key(x));
    if (it == cells_.end()) return false;
    for (int f : it->second) {
      const auto& t = t_[std::size_t(f)];
      const double h = h_[std::size_t(f)];
      if (triangle_distance2(x, v_[std::size_t(t[0])], v_[std::size_t(t[1])], v_[std::size_t(t[2])]) <= h * h)
        return true;
    }
    return false;
  }

 private:
  Cell key(const Vec3& x) const { return cell_of(x, cell_); }
  const std::vector<Vec3>& v_;
  const std::vector<std::array<int, 3>>& t_;
  double cell_;
  std::vector<double> h_;  // per triangle
  std::unordered_map<Cell, std::vector<int>, CellHash> cells_;
};

void check_params(const ConformParams& p) {
  if (!(p.min_dihedral >= 0 && p.min_dihedral < 60))
    throw UsageError("conforming_tets: min_dihedral " + format_number(p.min_dihedral) +
                     " degrees; expected 0 (no refinement) to below 60 (a regular tetrahedron has 70.5)");
  if (p.min_dihedral > 0 && !(p.radius_edge > 1 && std::isfinite(p.radius_edge)))
    throw UsageError("conforming_tets: radius-edge bound " + format_number(p.radius_edge) + "; expected a finite value > 1");
  if (p.optimise && !(p.max_dihedral > 90 && p.max_dihedral < 180))
    throw UsageError("conforming_tets: max_dihedral " + format_number(p.max_dihedral) +
                     " degrees; expected a value in (90, 180)");
  if (p.optimise && (p.optimise_level < 1 || p.optimise_level > 9))
    throw UsageError("conforming_tets: optimise level " + std::to_string(p.optimise_level) + "; expected 1 to 9");
  if (p.rounds < 1 || p.rounds > 5)
    throw UsageError("conforming_tets: " + std::to_string(p.rounds) + " rounds; expected 1 to 5");
  if (!(p.max_volume >= 0 && std::isfinite(p.max_volume)))
    throw UsageError("conforming_tets: max volume " + format_number(p.max_volume) + " world units^3; expected >= 0 (0: none)");
  if (!(p.boundary_clearance >= 0 && p.boundary_clearance < 1))
    throw UsageError("conforming_tets: boundary clearance " + format_number(p.boundary_clearance) +
                     " (times a triangle's longest edge); expected 0 (keep every point) to below 1");
  if (p.smooth_sweeps < 0)
    throw UsageError("conforming_tets: " + std::to_string(p.smooth_sweeps) + " smoothing sweeps; expected >= 0");
  if (!(p.point_tolerance > 0 && p.point_tolerance < 0.1))
    throw UsageError("conforming_tets: point tolerance " + format_number(p.point_tolerance) +
                     " (relative to the bounding-box diagonal); expected a value in (0, 0.1)");
}

// The boundary after validation: used vertices only, triangles renumbered.
struct Boundary {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> triangles;
  std::vector<std::array<int, 2>> labels;
  std::vector<int> materials;  // every label on some side, sorted
  bool single = true;          // one label pair
  double diagonal = 0;
};

Boundary check_boundary(const Mesh& m, const std::vector<std::array<int, 2>>& labels, const std::string& what) {
  const std::string w = "conforming_tets: " + what + ": ";
  const std::size_t nv = m.vertices.size(), nf = m.faces.size();
  if (nf < 4) throw InputError(w + std::to_string(nf) + " triangles; expected a closed surface (at least 4)");
  if (labels.size() != nf)
    throw InputError(w + std::to_string(labels.size()) + " label pairs for " + std::to_string(nf) +
                     " triangles; expected one (a, b) per triangle");
  Boundary b;
  std::vector<int> remap(nv, -1);
  std::size_t bad_label = 0, degenerate = 0;
  for (std::size_t f = 0; f < nf; ++f) {
    const auto& t = m.faces[f];
    for (int v : t)
      if (v < 0 || std::size_t(v) >= nv)
        throw InputError(w + "triangle " + std::to_string(f) + " has vertex index " + std::to_string(v) +
                         "; expected 0 to " + std::to_string(nv - 1));
    if (labels[f][0] >= labels[f][1]) ++bad_label;
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) ++degenerate;
    for (int v : t) remap[std::size_t(v)] = 0;
  }
  if (bad_label)
    throw InputError(w + std::to_string(bad_label) + " triangles have labels (a, b) with a >= b; expected a < b");
  for (std::size_t v = 0; v < nv; ++v) {
    if (remap[v] < 0) continue;
    if (!is_finite(m.vertices[v])) throw InputError(w + "vertex " + std::to_string(v) + " is not finite");
    remap[v] = int(b.vertices.size());
    b.vertices.push_back(m.vertices[v]);
  }
  Box bb;
  for (const Vec3& x : b.vertices) bb.extend(x);
  b.diagonal = norm(bb.size());
  {
    std::unordered_set<PointKey, PointKeyHash> seen;
    std::size_t dup = 0;
    for (const Vec3& x : b.vertices) {
      const double c[3] = {x.x, x.y, x.z};
      if (!seen.insert(key_of(c)).second) ++dup;
    }
    if (dup)
      throw InputError(w + std::to_string(dup) +
                       " vertices repeat the position of another vertex; expected "
                       "distinct vertices (merge them first)");
  }
  std::unordered_set<std::array<int, 3>, TriHash> tri_seen;
  std::size_t repeated = 0;
  for (std::size_t f = 0; f < nf; ++f) {
    std::array<int, 3> t;
    for (int i = 0; i < 3; ++i) t[i] = remap[std::size_t(m.faces[f][i])];
    const Vec3& a = b.vertices[std::size_t(t[0])];
    const Vec3& c = b.vertices[std::size_t(t[1])];
    const Vec3& d = b.vertices[std::size_t(t[2])];
    if (!(t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) && !(norm(cross(c - a, d - a)) > 0)) ++degenerate;
    if (!tri_seen.insert(sorted(t)).second) ++repeated;
    b.triangles.push_back(t);
    b.labels.push_back(labels[f]);
  }
  if (degenerate)
    throw InputError(w + std::to_string(degenerate) + " triangles have zero area; expected proper triangles");
  if (repeated)
    throw InputError(w + std::to_string(repeated) +
                     " triangles repeat another triangle's vertices; expected "
                     "each triangle once");
  for (const auto& l : b.labels)
    if (l != b.labels[0]) b.single = false;
  for (const auto& l : b.labels) b.materials.push_back(l[0]), b.materials.push_back(l[1]);
  std::sort(b.materials.begin(), b.materials.end());
  b.materials.erase(std::unique(b.materials.begin(), b.materials.end()), b.materials.end());

  // Closed: edge counts over all triangles, and over each material's triangles.
  std::unordered_map<std::uint64_t, int> count;
  std::map<int, std::unordered_map<std::uint64_t, int>> per;
  for (std::size_t f = 0; f < b.triangles.size(); ++f) {
    const auto& t = b.triangles[f];
    for (int i = 0; i < 3; ++i) {
      const std::uint64_t e = edge_key(t[i], t[(i + 1) % 3]);
      ++count[e];
      if (!b.single) {
        ++per[b.labels[f][0]][e];
        ++per[b.labels[f][1]][e];
      }
    }
  }
  std::size_t open = 0, over = 0;
  for (const auto& [e, c] : count) open += c == 1, over += c > 2;
  if (b.single && (open || over))
    throw InputError(w + "not a closed surface: " + std::to_string(open) + " edges in one triangle only, " +
                     std::to_string(over) + " in more than two; expected every edge in exactly 2 triangles");
  if (open)
    throw InputError(w + "not closed: " + std::to_string(open) +
                     " edges in one triangle only; expected every edge in at least 2 triangles");
  std::string odd;
  std::size_t odd_total = 0;
  for (const auto& [L, edges] : per) {
    std::size_t n = 0;
    for (const auto& [e, c] : edges) n += c % 2;
    if (n) odd += (odd.empty() ? "" : ", ") + std::to_string(n) + " of material " + std::to_string(L);
    odd_total += n;
  }
  if (odd_total)
    throw InputError(w + "a material's surface is not closed: " + std::to_string(odd_total) + " edges (" + odd +
                     ") are in an odd number of the triangles that have the material on one side; expected an "
                     "even number");
  return b;
}

// Intersecting triangles (CGAL), per material with several label pairs.
std::vector<int> check_self_intersections(const Boundary& b, const std::string& what) {
  Mesh m;
  m.vertices = b.vertices;
  m.faces = b.triangles;
  std::vector<int> untested;
  std::vector<std::pair<int, int>> pairs;
  if (b.single) {
    if (!self_intersecting_faces(m, pairs)) untested.push_back(b.labels[0][1]);
  } else {
    auto& la = m.face_ints["label_a"];
    auto& lb = m.face_ints["label_b"];
    for (const auto& l : b.labels) la.push_back(l[0]), lb.push_back(l[1]);
    pairs = material_self_intersections(m, b.materials, &untested);
  }
  if (!pairs.empty()) {
    std::unordered_set<int> faces;
    for (const auto& [x, y] : pairs) faces.insert(x), faces.insert(y);
    throw InputError("conforming_tets: " + what + ": self-intersecting: " + std::to_string(pairs.size()) +
                     " pairs of triangles cross (" + std::to_string(faces.size()) + " triangles, e.g. " +
                     std::to_string(pairs[0].first) + " and " + std::to_string(pairs[0].second) +
                     "); expected a surface that does not cross itself");
  }
  return untested;
}

// Every point a step returned, by global index: the boundary vertices, then
// the interior candidates, then Steiner points as they appear.
struct Registry {
  std::vector<Vec3> points;
  std::size_t boundary = 0, interior = 0;
  std::unordered_map<PointKey, int, PointKeyHash> index;
  int add(const Vec3& x) {
    const double c[3] = {x.x, x.y, x.z};
    const auto [it, fresh] = index.emplace(key_of(c), int(points.size()));
    if (fresh) points.push_back(x);
    return it->second;
  }
};

// One step's tetrahedra in global indices, with TetGen's region number.
struct Snapshot {
  std::vector<std::array<int, 4>> tets;
  std::vector<int> region;
};

Snapshot snapshot(const tetgenio& out, Registry& reg, const std::string& step, const std::string& what) {
  if (out.numberoftetrahedra <= 0 || out.numberofcorners != 4 || out.numberoftetrahedronattributes < 1)
    throw InputError("conforming_tets: " + what + ": step \"" + step + "\": TetGen returned " +
                     std::to_string(out.numberoftetrahedra) + " tetrahedra with " +
                     std::to_string(out.numberoftetrahedronattributes) +
                     " region attributes; expected tetrahedra with a region each");
  std::vector<int> g(std::size_t(out.numberofpoints));
  for (int i = 0; i < out.numberofpoints; ++i)
    g[std::size_t(i)] = reg.add({out.pointlist[3 * i], out.pointlist[3 * i + 1], out.pointlist[3 * i + 2]});
  Snapshot s;
  const std::size_t nt = std::size_t(out.numberoftetrahedra), na = std::size_t(out.numberoftetrahedronattributes);
  s.tets.resize(nt);
  s.region.resize(nt);
  for (std::size_t t = 0; t < nt; ++t) {
    std::array<int, 4> v;
    for (int i = 0; i < 4; ++i) v[i] = g[std::size_t(out.tetrahedronlist[4 * t + i])];
    const Vec3 &a = reg.points[v[0]], &b = reg.points[v[1]], &c = reg.points[v[2]], &d = reg.points[v[3]];
    if (dot(b - a, cross(c - a, d - a)) < 0) std::swap(v[0], v[1]);
    s.tets[t] = v;
    s.region[t] = int(std::lround(out.tetrahedronattributelist[t * na]));
  }
  return s;
}

struct Vote {
  std::map<int, int> label;  // region -> material
  std::size_t split = 0;
  double min_share = 1;  // smallest winning share of a region's volume
};

Vote vote(const Snapshot& s, const Registry& reg, const std::function<int(const Vec3&)>& label_at) {
  std::map<int, std::map<int, double>> volume;  // region -> material -> volume
  for (std::size_t t = 0; t < s.tets.size(); ++t) {
    const auto& v = s.tets[t];
    const Vec3 &a = reg.points[v[0]], &b = reg.points[v[1]], &c = reg.points[v[2]], &d = reg.points[v[3]];
    const double vol = std::fabs(dot(b - a, cross(c - a, d - a))) / 6.0;
    volume[s.region[t]][label_at((a + b + c + d) * 0.25)] += vol;
  }
  Vote r;
  for (const auto& [region, by] : volume) {
    int best = by.begin()->first;
    for (const auto& [m, vol] : by)
      if (vol > by.at(best)) best = m;
    r.label[region] = best;
    r.split += by.size() > 1;
    double total = 0;
    for (const auto& [m, vol] : by) total += vol;
    if (total > 0) r.min_share = std::min(r.min_share, by.at(best) / total);
  }
  return r;
}

// The kept tetrahedra of a step as a LabelledTets (vertices used, in global order).
LabelledTets assemble(const Snapshot& s, const Vote& v, int outside, const Registry& reg, const Boundary& b,
                      std::size_t& steiner, const std::string& step, const std::string& what) {
  std::vector<int> local(reg.points.size(), -1);
  std::vector<std::size_t> kept;
  std::vector<int> material(s.tets.size());
  for (std::size_t t = 0; t < s.tets.size(); ++t) {
    const auto it = v.label.find(s.region[t]);
    if (it == v.label.end())
      throw InputError("conforming_tets: " + what + ": step \"" + step + "\": TetGen returned region " +
                       std::to_string(s.region[t]) + ", which the first step did not have (internal error)");
    material[t] = it->second;
  }
  for (std::size_t t = 0; t < s.tets.size(); ++t)
    if (material[t] != outside) {
      kept.push_back(t);
      for (int g : s.tets[t]) local[std::size_t(g)] = 0;
    }
  for (std::size_t i = 0; i < b.vertices.size(); ++i) local[i] = 0;  // always first, in order
  LabelledTets lt;
  steiner = 0;
  for (std::size_t g = 0; g < reg.points.size(); ++g)
    if (local[g] == 0) {
      local[g] = int(lt.vertices.size());
      lt.vertices.push_back(reg.points[g]);
      steiner += g >= reg.boundary + reg.interior;
    }
  for (std::size_t t : kept) {
    std::array<int, 4> q;
    for (int i = 0; i < 4; ++i) q[i] = local[std::size_t(s.tets[t][i])];
    lt.tets.push_back(q);
    lt.materials.push_back(material[t]);
  }
  lt.triangles = b.triangles;  // boundary vertices keep their indices
  lt.triangle_labels = b.labels;
  return lt;
}

// The faces where the material changes must be the input triangles, with
// the label pairs of the materials on their two sides.
void check_faces(const LabelledTets& lt, const TetQuality& q, int outside, int boundary_vertices,
                 const std::string& step, const std::string& what) {
  const std::string w = "conforming_tets: " + what + ": step \"" + step + "\": ";
  if (q.triangles_missing || q.triangles_extra)
    throw InputError(w + std::to_string(q.triangles_extra) + " input triangles are not faces where the material " +
                     "changes and " + std::to_string(q.triangles_missing) + " such faces are no input triangle " +
                     "(two regions on either side of a triangle voted the same material, or label_at disagrees " +
                     "with the triangles); expected the input triangles exactly");
  // A triangle's corners are boundary vertices, the first ones: only faces
  // with three of them can be triangles.
  constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  std::unordered_map<std::array<int, 3>, std::array<int, 2>, TriHash> sides;  // materials on the two sides
  for (std::size_t t = 0; t < lt.tets.size(); ++t)
    for (const auto& f : kFace) {
      const std::array<int, 3> k = sorted({lt.tets[t][f[0]], lt.tets[t][f[1]], lt.tets[t][f[2]]});
      if (k[2] >= boundary_vertices) continue;
      auto it = sides.find(k);
      if (it == sides.end())
        sides.emplace(k, std::array<int, 2>{lt.materials[t], outside});
      else
        it->second[1] = lt.materials[t];
    }
  std::size_t wrong = 0, first = 0;
  std::array<int, 2> got{}, want{};
  for (std::size_t i = 0; i < lt.triangles.size(); ++i) {
    auto m = sides.at(sorted(lt.triangles[i]));
    if (m[0] > m[1]) std::swap(m[0], m[1]);
    if (m != lt.triangle_labels[i]) {
      if (!wrong++) first = i, got = m, want = lt.triangle_labels[i];
    }
  }
  if (wrong)
    throw InputError(w + std::to_string(wrong) +
                     " triangles separate other materials than their labels say, e.g. "
                     "triangle " +
                     std::to_string(first) + " labelled (" + std::to_string(want[0]) + ", " + std::to_string(want[1]) +
                     ") between materials " + std::to_string(got[0]) + " and " + std::to_string(got[1]) +
                     "; expected label_at to agree with the triangles' labels");
}

// A TetGen pass; failures become an InputError naming the step.
void run_tetgen(tetgenbehavior& b, tetgenio& in, tetgenio& out, tetgenio* addin, const std::string& step,
                const std::string& what) {
  try {
    tetrahedralize(&b, &in, &out, addin, nullptr);
  } catch (int code) {
    const std::string why = tetgen_failure(code);
    throw InputError("conforming_tets: " + what + ": step \"" + step + "\": TetGen failed with code " +
                     std::to_string(code) + (why.empty() ? "" : " (" + why + ")") +
                     (code == 3 || code == 5 ? "; expected a surface that does not cross or touch itself" : ""));
  }
}

void parse(tetgenbehavior& b, const char* switches) {
  std::vector<char> s(switches, switches + std::strlen(switches) + 1);
  if (!b.parse_commandline(s.data()))
    throw InputError(std::string("conforming_tets: TetGen refused switches ") + switches);
}

template <class T>
T* copy_array(const T* src, std::size_t n) {
  T* a = new T[n];
  std::copy(src, src + n, a);
  return a;
}

// The previous pass's output as the next pass's input (-r): points,
// tetrahedra with their regions, the boundary faces and segments.
void reload(const tetgenio& out, tetgenio& in) {
  in.firstnumber = 0;
  in.numberofpoints = out.numberofpoints;
  in.pointlist = copy_array(out.pointlist, std::size_t(out.numberofpoints) * 3);
  in.numberoftetrahedra = out.numberoftetrahedra;
  in.numberofcorners = 4;
  in.tetrahedronlist = copy_array(out.tetrahedronlist, std::size_t(out.numberoftetrahedra) * 4);
  in.numberoftetrahedronattributes = out.numberoftetrahedronattributes;
  in.tetrahedronattributelist =
      copy_array(out.tetrahedronattributelist,
                 std::size_t(out.numberoftetrahedra) * std::size_t(out.numberoftetrahedronattributes));
  in.numberoftrifaces = out.numberoftrifaces;
  in.trifacelist = copy_array(out.trifacelist, std::size_t(out.numberoftrifaces) * 3);
  if (out.trifacemarkerlist)
    in.trifacemarkerlist = copy_array(out.trifacemarkerlist, std::size_t(out.numberoftrifaces));
  if (out.numberofedges > 0 && out.edgelist) {
    in.numberofedges = out.numberofedges;
    in.edgelist = copy_array(out.edgelist, std::size_t(out.numberofedges) * 2);
    if (out.edgemarkerlist) in.edgemarkerlist = copy_array(out.edgemarkerlist, std::size_t(out.numberofedges));
  }
}

}  // namespace

ConformResult conforming_tets(const Mesh& boundary, const std::vector<std::array<int, 2>>& triangle_labels,
                              const std::vector<Vec3>& interior, const std::function<int(const Vec3&)>& label_at,
                              int outside_label, const ConformParams& p, const std::string& what) {
  check_params(p);
  ConformResult res;
  std::optional<ScopedStage> checks("conform_checks");
  const Boundary b = check_boundary(boundary, triangle_labels, what);
  res.unused_boundary_vertices = boundary.vertices.size() - b.vertices.size();
  res.self_intersection_untested = check_self_intersections(b, what);

  // Interior points: inside a material, not on top of another point.
  Registry reg;
  for (const Vec3& x : b.vertices) reg.add(x);
  reg.boundary = b.vertices.size();
  res.interior_given = interior.size();
  // TetGen would insert a point on a triangle into the triangle (splitting
  // it, -Y notwithstanding): such points go, as do points on other points.
  const double tol = p.point_tolerance * b.diagonal;
  PointGrid grid(tol);
  for (const Vec3& x : b.vertices) grid.add(x);
  double mean_edge = 0;
  for (const auto& t : b.triangles) mean_edge += norm(b.vertices[std::size_t(t[1])] - b.vertices[std::size_t(t[0])]);
  mean_edge /= double(b.triangles.size());
  const TriangleGrid near_triangle(b.vertices, b.triangles, std::max(mean_edge, 4 * tol), tol);
  std::unique_ptr<TriangleGrid> too_close;
  if (p.boundary_clearance > 0)
    too_close = std::make_unique<TriangleGrid>(b.vertices, b.triangles, std::max(mean_edge, 4 * tol), tol,
                                               p.boundary_clearance);
  std::vector<Vec3> candidates;
  for (std::size_t i = 0; i < interior.size(); ++i) {
    const Vec3& x = interior[i];
    if (!is_finite(x)) throw InputError("conforming_tets: interior point " + std::to_string(i) + " is not finite");
    if (label_at(x) == outside_label) {
      ++res.interior_outside;
      continue;
    }
    if (grid.near(x) || near_triangle.near(x)) {
      ++res.interior_near_point;
      continue;
    }
    if (too_close && too_close->near(x)) {
      ++res.interior_near_boundary;
      continue;
    }
    grid.add(x);
    candidates.push_back(x);
    reg.add(x);
  }
  reg.interior = candidates.size();
  checks.reset();

  // The regions vote once, on the first step; later steps keep TetGen's
  // region numbers (-r carries them).
  Vote v;
  bool need_vote = true;
  std::string pass_suffix;  // " 2", " 3": the passes after removing interior points of bad tetrahedra
  auto measure = [&](const std::string& step, const tetgenio& out, double seconds) {
    const std::string name = step + pass_suffix;
    const Snapshot s = snapshot(out, reg, name, what);
    if (need_vote) {
      need_vote = false;
      v = vote(s, reg, label_at);
      res.regions = v.label.size();
      res.split_vote_regions = v.split;
      res.min_vote_share = v.min_share;
      for (const auto& [r, m] : v.label) res.dropped_regions += m == outside_label;
      if (res.dropped_regions == res.regions)
        throw InputError("conforming_tets: " + what + ": every region (" + std::to_string(res.regions) +
                         ") is outside (label " + std::to_string(outside_label) +
                         ") by label_at; expected a material inside the surface");
    }
    ScopedStage stage("conform_measure");
    ConformStep st;
    st.name = name;
    st.seconds = seconds;
    res.mesh = assemble(s, v, outside_label, reg, b, st.steiner_points, name, what);
    st.quality = tet_quality(res.mesh);
    check_faces(res.mesh, st.quality, outside_label, int(b.vertices.size()), name, what);
    st.vertices = res.mesh.vertices.size();
    st.tets = res.mesh.tets.size();
    st.share_25_140 = st.quality.overall.share_25_140();  // counted by tet_quality
    if (p.progress) {
      const TetStats& o = st.quality.overall;
      info("conform " + name + ": " + std::to_string(st.tets) + " tetrahedra, " + std::to_string(st.vertices) +
           " vertices (" + std::to_string(st.steiner_points) + " Steiner), dihedral " + format_number(o.dihedral_min) + ".." +
           format_number(o.dihedral_max) + " deg, " + format_number(100 * st.share_25_140) + "% in [25, 140], radius ratio mean " +
           format_number(o.rr_mean) + ", " + format_number(seconds) + " s");
    }
    res.steps.push_back(st);
  };

  // One meshing: steps 1-3 on the interior points `cand`.
  auto mesh_once = [&](const std::vector<Vec3>& cand) {
    need_vote = true;
    // Step 1: constrained Delaunay of the triangles plus the interior points.
    auto in = std::make_unique<tetgenio>();
    in->firstnumber = 0;
    // The interior points go in with the boundary vertices: TetGen keeps
    // vertices of no facet, and one Delaunay of all points is much faster
    // than inserting them afterwards (-i; frog5: 22 s -> 1.7 s).
    const std::size_t np = b.vertices.size() + cand.size();
    in->numberofpoints = int(np);
    in->pointlist = new REAL[np * 3];
    for (std::size_t i = 0; i < np; ++i) {
      const Vec3& x = i < b.vertices.size() ? b.vertices[i] : cand[i - b.vertices.size()];
      in->pointlist[3 * i] = x.x;
      in->pointlist[3 * i + 1] = x.y;
      in->pointlist[3 * i + 2] = x.z;
    }
    in->numberoffacets = int(b.triangles.size());
    in->facetlist = new tetgenio::facet[b.triangles.size()];
    in->facetmarkerlist = new int[b.triangles.size()];
    for (std::size_t f = 0; f < b.triangles.size(); ++f) {
      tetgenio::facet& fc = in->facetlist[f];
      fc.numberofpolygons = 1;
      fc.polygonlist = new tetgenio::polygon[1];
      fc.numberofholes = 0;
      fc.holelist = nullptr;
      fc.polygonlist[0].numberofvertices = 3;
      fc.polygonlist[0].vertexlist = new int[3];
      for (int k = 0; k < 3; ++k) fc.polygonlist[0].vertexlist[k] = b.triangles[f][k];
      in->facetmarkerlist[f] = int(f) + 1;
    }
    auto out = std::make_unique<tetgenio>();
    {
      // p: PLC, Y: keep the boundary, M: do not merge coplanar triangles (which
      // would let TetGen re-triangulate them), A: regions, i: interior points.
      tetgenbehavior tb;
      parse(tb, "pYMAzQ");
      tb.optlevel = 0;  // the plain constrained Delaunay tetrahedralisation
      Stopwatch sw;
      run_tetgen(tb, *in, *out, nullptr, "cdt", what);
      measure("cdt", *out, sw.seconds());
    }
    // Steps 2 and 3, as -r passes on the previous output: quality refinement
    // (Steiner points inside the volume), then sliver removal (flips,
    // smoothing, point insertion; boundary vertices stay).
    auto pass = [&](const std::string& name, bool refine) {
      auto next_in = std::make_unique<tetgenio>();
      reload(*out, *next_in);
      in = std::move(next_in);
      out = std::make_unique<tetgenio>();
      tetgenbehavior tb;
      if (refine) {
        parse(tb, ("rYzQq" + format_number(p.radius_edge) + "/" + format_number(p.min_dihedral) +
                   (p.max_volume > 0 ? "a" + format_number(p.max_volume) : std::string()))
                      .c_str());
        tb.optlevel = 0;
      } else {
        parse(tb, "rYzQ");
        tb.optlevel = p.optimise_level;
        tb.optscheme = 7;
        // One bound for TetGen's three: flips aim at angles above it, and
        // smoothing and point insertion (which its defaults, 179°, keep for
        // nearly flat tetrahedra) work on the same tetrahedra. Measured on
        // nested icospheres: max dihedral 145° -> 140°, min 20.7° -> 22.3°.
        tb.optmaxdihedral = p.max_dihedral;
        tb.optminsmtdihed = p.max_dihedral;
        tb.optminslidihed = p.max_dihedral;
      }
      Stopwatch sw;
      run_tetgen(tb, *in, *out, nullptr, name, what);
      measure(name, *out, sw.seconds());
    };
    for (int round = 1; round <= p.rounds; ++round) {
      const std::string suffix = round == 1 ? "" : " " + std::to_string(round);
      // Later rounds only while the previous left an angle below the bound
      // (the optimisation's inserted points can make a few small ones).
      if (round > 1 && !(p.min_dihedral > 0 && res.steps.back().quality.overall.dihedral_min < p.min_dihedral)) break;
      if (p.min_dihedral > 0) pass("refine" + suffix, true);
      if (p.optimise) pass("optimise" + suffix, false);
    }
  };
  // ODT smoothing and sliver perturbation of every vertex TetGen may move
  // (interior points and Steiner points follow the boundary vertices).
  std::size_t smooth_moves = 0;  // of the last smoothing
  auto smooth = [&]() {
    Stopwatch sw;
    TetSmoothParams sp;
    sp.sweeps = p.smooth_sweeps;
    const TetSmoothResult sr = odt_smooth(res.mesh, b.vertices.size(), sp);
    ConformStep st;
    st.name = "smooth" + pass_suffix;
    st.seconds = sw.seconds();
    {
      ScopedStage stage("conform_measure");
      st.quality = tet_quality(res.mesh);
      check_faces(res.mesh, st.quality, outside_label, int(b.vertices.size()), st.name, what);
    }
    st.vertices = res.mesh.vertices.size();
    st.tets = res.mesh.tets.size();
    st.steiner_points = res.steps.back().steiner_points;
    st.share_25_140 = st.quality.overall.share_25_140();  // counted by tet_quality
    smooth_moves = sr.moves;
    if (p.progress) {
      const TetStats& o = st.quality.overall;
      info("conform " + st.name + ": " + std::to_string(sr.moves) + " moves in " + std::to_string(sr.sweeps) +
           " sweeps (" + format_number(sr.odt_seconds) + " s), " + std::to_string(sr.perturbed) + " of " +
           std::to_string(sr.perturb_candidates) + " sliver vertices perturbed (" + format_number(sr.perturb_seconds) +
           " s), dihedral " + format_number(o.dihedral_min) + ".." + format_number(o.dihedral_max) + " deg, " +
           format_number(100 * st.share_25_140) + "% in [25, 140], radius ratio mean " + format_number(o.rr_mean) + ", " +
           format_number(st.seconds) + " s");
    }
    res.steps.push_back(st);
  };
  // Sliver removal by point removal: TetGen cannot move the boundary (-Y),
  // so a bad tetrahedron next to it often has an interior point too close to
  // a boundary triangle. When tetrahedra outside [exude_below, exude_above]
  // survive the smoothing, their interior points go and the volume is meshed
  // again, up to exude_rounds times (brain mask: none survive, one meshing;
  // nested head: 376 points removed, 0.9..178° -> 15.7..146°).
  // Each meshing is a new TetGen run whose outcome differs a little: the
  // round with the fewest tetrahedra outside the band is kept.
  std::vector<Vec3> cand = candidates;
  LabelledTets best;
  std::size_t best_bad = std::numeric_limits<std::size_t>::max(), best_step = 0, best_kept = 0;
  for (int ex = 0;; ++ex) {
    pass_suffix = ex == 0 ? "" : " " + std::to_string(ex + 1);
    mesh_once(cand);
    const std::size_t nb = b.vertices.size();
    const std::size_t kept = res.mesh.vertices.size() - nb - res.steps.back().steiner_points;
    // The interior points of the tetrahedra outside the band as TetGen left
    // them are the ones to remove (the smoothing may have repaired their
    // tetrahedra and left the cause, a point too close to the boundary).
    auto outside_band = [&](const LabelledTets& m, std::set<std::array<double, 3>>* points) {
      std::vector<std::size_t> idx;
      const std::size_t n = tets_outside_band(m, nb, nb + kept, p.exude_below, p.exude_above, points ? &idx : nullptr);
      for (std::size_t k : idx) {
        const Vec3& x = m.vertices[k];
        points->insert({x.x, x.y, x.z});
      }
      return n;
    };
    std::set<std::array<double, 3>> bad;
    if (ex < p.exude_rounds) outside_band(res.mesh, &bad);
    // Only tetrahedra still outside after the smoothing call for a new meshing.
    if (p.smooth_sweeps > 0) smooth();
    const std::size_t bad_tets = outside_band(res.mesh, nullptr);
    if (bad_tets == 0) bad.clear();
    if (bad_tets < best_bad) {
      best_bad = bad_tets;
      best_step = res.steps.size() - 1;
      best_kept = kept;
      res.smooth_moves = smooth_moves;
      if (ex < p.exude_rounds && !bad.empty()) best = res.mesh;  // a later round may be worse
    }
    if (ex >= p.exude_rounds) break;
    if (bad.empty()) break;
    std::vector<Vec3> next;
    next.reserve(cand.size());
    for (const Vec3& x : cand)
      if (!bad.count({x.x, x.y, x.z})) next.push_back(x);
    if (next.size() == cand.size()) break;
    res.interior_exuded += cand.size() - next.size();
    if (p.progress)
      info("conform: " + std::to_string(bad_tets) + " tetrahedra outside [" + format_number(p.exude_below) + ", " +
           format_number(p.exude_above) + "] degrees left; the " + std::to_string(cand.size() - next.size()) +
           " interior points of the tetrahedra TetGen left outside removed, meshing again");
    cand.swap(next);
  }
  if (best_step + 1 != res.steps.size()) {
    res.mesh = std::move(best);
    ConformStep again = res.steps[best_step];  // the last step is always the mesh returned
    again.name = "keep " + again.name;
    again.seconds = 0;
    res.steps.push_back(again);
    if (p.progress)
      info("conform: keeping step \"" + res.steps[best_step].name + "\" (" + std::to_string(best_bad) +
           " tetrahedra outside [" + format_number(p.exude_below) + ", " + format_number(p.exude_above) + "] degrees)");
  }
  const ConformStep& kept_step = res.steps[best_step];
  res.kept_step = kept_step.name;
  res.steiner_points = kept_step.steiner_points;
  res.interior_kept = best_kept;
  // Candidates of the kept round that TetGen did not use (the removed ones are not counted again).
  res.interior_refused = candidates.size() > res.interior_exuded + res.interior_kept
                             ? candidates.size() - res.interior_exuded - res.interior_kept
                             : 0;
  return res;
}

std::size_t tets_outside_band(const LabelledTets& m, std::size_t first, std::size_t last, double below, double above,
                              std::vector<std::size_t>* remove) {
  auto movable = [&](int k) { return std::size_t(k) >= first && std::size_t(k) < last; };
  std::vector<char> take(remove ? m.vertices.size() : 0, 0), ring;
  auto take_tet = [&](const std::array<int, 4>& t) {
    for (int k : t)
      if (movable(k)) take[std::size_t(k)] = 1;
  };
  std::size_t n = 0;
  for (const auto& t : m.tets) {
    const DihedralRange d = tet_dihedral_range(m.vertices[std::size_t(t[0])], m.vertices[std::size_t(t[1])],
                                               m.vertices[std::size_t(t[2])], m.vertices[std::size_t(t[3])]);
    if (d.min >= below && d.max <= above) continue;
    ++n;
    if (!remove) continue;
    if (std::any_of(t.begin(), t.end(), movable)) {
      take_tet(t);
    } else {
      ring.resize(m.vertices.size(), 0);
      for (int k : t) ring[std::size_t(k)] = 1;
    }
  }
  if (remove) {
    if (!ring.empty())
      for (const auto& t : m.tets)
        if (std::any_of(t.begin(), t.end(), [&](int k) { return ring[std::size_t(k)] != 0; })) take_tet(t);
    remove->clear();
    for (std::size_t k = 0; k < take.size(); ++k)
      if (take[k]) remove->push_back(k);
  }
  return n;
}

Json to_json(const std::vector<ConformStep>& steps_in) {
  Json steps = Json::array();
  for (const ConformStep& s : steps_in) {
    Json q = to_json(s.quality);
    q["share_25_140"] = s.share_25_140;
    steps.push_back({{"name", s.name},
                     {"seconds", s.seconds},
                     {"vertices", s.vertices},
                     {"tetrahedra", s.tets},
                     {"steiner_points", s.steiner_points},
                     {"quality", q}});
  }
  return steps;
}

Json to_json(const ConformResult& r) {
  return {{"steps", to_json(r.steps)},
          {"counts",
           {{"vertices", r.mesh.vertices.size()},
            {"tetrahedra", r.mesh.tets.size()},
            {"triangles", r.mesh.triangles.size()},
            {"steiner_points", r.steiner_points},
            {"regions", r.regions},
            {"dropped_regions", r.dropped_regions},
            {"split_vote_regions", r.split_vote_regions}, {"min_vote_share", r.min_vote_share},
            {"unused_boundary_vertices", r.unused_boundary_vertices},
            {"interior_given", r.interior_given},
            {"interior_kept", r.interior_kept},
            {"interior_exuded", r.interior_exuded},
            {"kept_step", r.kept_step},
            {"smooth_moves", r.smooth_moves},
            {"interior_outside", r.interior_outside},
            {"interior_near_point", r.interior_near_point},
            {"interior_near_boundary", r.interior_near_boundary},
            {"interior_refused", r.interior_refused},
            {"self_intersection_untested", r.self_intersection_untested}}}};
}

}  // namespace pm
