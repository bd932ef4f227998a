#include "pm/mesh/meshstats.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <unordered_set>

#include "pm/base/error.h"
#include "pm/base/parallel.h"
#include "pm/mesh/quad_mesh.h"

namespace pm {
namespace {

// Distance from x to the surface F = iso by damped Newton projection along the
// gradient (steps capped at the field's resolution so flat regions of e.g. a
// binary mask cannot throw the point away). Returns NaN when it does not
// reach |F - iso| small within the iteration budget.
double surface_distance(const ScalarField& f, double iso, const Vec3& x0) {
  Vec3 x = x0, g;
  const double cap = f.resolution();
  for (int it = 0; it < 60; ++it) {
    const double v = f.value_gradient(x, g) - iso;
    const double g2 = norm2(g);
    if (!(g2 > 0)) return std::nan("");
    Vec3 step = g * (v / g2);
    const double len = norm(step);
    if (len > cap) step *= cap / len;
    x -= step;
    if (len < 1e-9 * (1 + norm(x))) return norm(x - x0);
  }
  const double v = f.value_gradient(x, g) - iso;
  return std::fabs(v) <= 1e-6 * (1 + norm(g)) ? norm(x - x0) : std::nan("");
}

double radius_ratio(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double la = norm(b - c), lb = norm(c - a), lc = norm(a - b);
  const double area2 = norm(cross(b - a, c - a));  // 2A
  const double per = la + lb + lc;
  const double denom = per * la * lb * lc;
  // 2 r_in / r_circ = 2 (2A/P) / (abc / 4A) = 16 A² / (P abc) = 4 (2A)² / (P abc)
  return denom > 0 ? 4.0 * area2 * area2 / denom : 0.0;
}

}  // namespace

CreaseCount count_creases(const Mesh& m, const std::vector<int>& faces, double angle_deg) {
  const std::size_t n = faces.empty() ? m.faces.size() : faces.size();
  auto face_at = [&](std::size_t i) { return faces.empty() ? int(i) : faces[i]; };
  // Directed edge (u, v) of a face, keyed by (min, max), with the face and
  // the direction it runs through it (+1: min -> max); sorted, so each
  // edge's uses come together (an interior edge has exactly two).
  struct Use {
    std::uint64_t key;
    int face, dir;
    bool operator<(const Use& o) const { return key < o.key || (key == o.key && face < o.face); }
  };
  std::vector<Use> uses(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const int f = face_at(i);
    for (int e = 0; e < 3; ++e) {
      int a = m.faces[f][e], b = m.faces[f][(e + 1) % 3];
      const int dir = a < b ? 1 : -1;
      if (a > b) std::swap(a, b);
      uses[3 * i + std::size_t(e)] = {(std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b), f, dir};
    }
  }
  std::sort(uses.begin(), uses.end());
  auto normal = [&](int f) {
    const auto& t = m.faces[f];
    return cross(m.vertices[t[1]] - m.vertices[t[0]], m.vertices[t[2]] - m.vertices[t[0]]);
  };
  const double cos_limit = std::cos(angle_deg * M_PI / 180);
  CreaseCount c;
  for (std::size_t g = 0; g < uses.size();) {
    std::size_t e = g + 1;
    while (e < uses.size() && uses[e].key == uses[g].key) ++e;
    if (e - g == 2) {
      const Vec3 n0 = normal(uses[g].face);
      Vec3 n1 = normal(uses[g + 1].face);
      const double l0 = norm(n0), l1 = norm(n1);
      if (l0 > 0 && l1 > 0) {
        if (uses[g].dir == uses[g + 1].dir) n1 = n1 * -1.0;  // same direction through the edge: orientations disagree
        ++c.interior_edges;
        c.creased += dot(n0, n1) / (l0 * l1) < cos_limit;
      }
    }
    g = e;
  }
  return c;
}

namespace {

// Distances of points 0..n-1 to the surface, in parallel; NaN where the
// projection fails, 0 for the points `point` declines (returns false).
template <class Point>
std::vector<double> surface_distances(const ScalarField& f, double iso, std::size_t n, const Point& point) {
  std::vector<double> d(n, 0.0);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
    Vec3 x;
    for (std::size_t i = r.begin(); i != r.end(); ++i)
      if (point(i, x)) d[i] = surface_distance(f, iso, x);
  });
  return d;
}

void measure_without_self_intersections(const Mesh& m, const MeshQualityParams& p, MeshQuality& q) {
  q.rr_min = 1e300;
  q.min_angle_deg = 180;
  double rr_sum = 0;
  for (const auto& f : m.faces) {
    const Vec3 &a = m.vertices[f[0]], &b = m.vertices[f[1]], &c = m.vertices[f[2]];
    const double rr = radius_ratio(a, b, c);
    q.rr_min = std::min(q.rr_min, rr);
    rr_sum += rr;
    ++q.rr_histogram[std::min<std::size_t>(9, std::size_t(std::max(0.0, rr) * 10))];
    const Vec3* v[3] = {&a, &b, &c};
    for (int i = 0; i < 3; ++i) {
      const Vec3 e1 = *v[(i + 1) % 3] - *v[i], e2 = *v[(i + 2) % 3] - *v[i];
      const double den = norm(e1) * norm(e2);
      const double ang = den > 0 ? std::acos(std::clamp(dot(e1, e2) / den, -1.0, 1.0)) * 180 / M_PI : 0;
      q.min_angle_deg = std::min(q.min_angle_deg, ang);
      q.max_angle_deg = std::max(q.max_angle_deg, ang);
    }
  }
  q.rr_mean = rr_sum / double(m.faces.size());

  // Unique edges (in the order the faces first name them, so that the sums
  // below do not depend on the standard library's hashing) and valences.
  std::unordered_set<std::uint64_t> seen;
  seen.reserve(m.faces.size() * 2);
  std::vector<std::uint64_t> edges;
  edges.reserve(m.faces.size() * 3 / 2 + 3);
  std::vector<int> valence(m.vertices.size(), 0);
  for (const auto& f : m.faces)
    for (int e = 0; e < 3; ++e) {
      int a = f[e], b = f[(e + 1) % 3];
      if (a > b) std::swap(a, b);
      const std::uint64_t key = (std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b);
      if (seen.insert(key).second) {
        edges.push_back(key);
        ++valence[a];
        ++valence[b];
      }
    }
  std::size_t used = 0, v6 = 0, out57 = 0;
  for (int k : valence) {
    if (k == 0) continue;
    ++used;
    ++q.valence_histogram[std::min(k, 15)];
    v6 += k == 6;
    out57 += k < 5 || k > 7;
  }
  q.valence6_share = used ? double(v6) / double(used) : 0;
  q.valence_outside_5_7_share = used ? double(out57) / double(used) : 0;

  double len_sum = 0;
  std::size_t le2 = 0, counted = 0;
  double ratio_sum = 0;
  for (std::uint64_t key : edges) {
    const int a = int(key >> 32), b = int(key & 0xffffffffu);
    const double len = norm(m.vertices[a] - m.vertices[b]);
    len_sum += len;
    if (p.sizing) {
      double ha = 0, hb = 0;
      if (!p.sizing->sample(m.vertices[a], ha) || !p.sizing->sample(m.vertices[b], hb)) continue;
      const double r = len / (0.5 * (ha + hb));
      q.edge_h_max = std::max(q.edge_h_max, r);
      ratio_sum += r;
      le2 += r <= 2.0;
      ++counted;
    }
  }
  q.edge_length_mean = len_sum / double(edges.size());
  if (p.sizing) {
    q.has_sizing = true;
    q.edge_h_mean = counted ? ratio_sum / double(counted) : 0;
    q.edge_le_2h_share = counted ? double(le2) / double(counted) : 0;
  }

  if (p.field) {
    q.has_field = true;
    std::vector<char> is_used(m.vertices.size(), 0);
    for (const auto& f : m.faces)
      for (int v : f) is_used[v] = 1;
    // Computed in parallel, summed in order: the same bits for any thread count.
    const std::vector<double> dv = surface_distances(*p.field, p.iso, m.vertices.size(), [&](std::size_t i, Vec3& x) {
      x = m.vertices[i];
      return is_used[i] != 0;
    });
    double sum = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < m.vertices.size(); ++i)
      if (is_used[i]) {
        const double d = dv[i];
        if (std::isnan(d)) {
          ++q.dist_failed;
          continue;
        }
        q.dist_vertex_max = std::max(q.dist_vertex_max, d);
        sum += d;
        ++n;
      }
    q.dist_vertex_mean = n ? sum / double(n) : 0;
    sum = 0;
    n = 0;
    const std::vector<double> dc = surface_distances(*p.field, p.iso, m.faces.size(), [&](std::size_t i, Vec3& x) {
      const auto& f = m.faces[i];
      x = (m.vertices[f[0]] + m.vertices[f[1]] + m.vertices[f[2]]) / 3.0;
      return true;
    });
    for (const double d : dc) {
      if (std::isnan(d)) {
        ++q.dist_failed;
        continue;
      }
      q.dist_centroid_max = std::max(q.dist_centroid_max, d);
      sum += d;
      ++n;
    }
    q.dist_centroid_mean = n ? sum / double(n) : 0;
  }
  const CreaseCount creases = count_creases(m);
  q.interior_edges = creases.interior_edges;
  q.creased_edges_20 = creases.creased;
  q.crease_share_20 = creases.share();
}

}  // namespace

MeshQuality mesh_quality(const Mesh& m, const MeshQualityParams& p) {
  m.validate("mesh_quality");
  MeshQuality q;
  q.faces = m.faces.size();
  q.topology = mesh_topology(m);
  q.vertices = q.topology.vertices;
  q.rr_histogram.assign(10, 0);
  q.valence_histogram.assign(16, 0);
  if (m.faces.empty()) return q;
  // The self-intersection test (CGAL, the largest part) runs beside the rest.
  pm::parallel_for(0, 2, [&](int task) {
    if (task == 0) {
      if (p.self_intersections) q.self_intersecting_pairs = count_self_intersections(m);
    } else {
      measure_without_self_intersections(m, p, q);
    }
  });
  return q;
}

Json to_json(const MeshQuality& q) {
  Json j;
  j["vertices"] = q.vertices;
  j["faces"] = q.faces;
  j["radius_ratio"] = {{"min", q.rr_min}, {"mean", q.rr_mean}, {"histogram", q.rr_histogram}};
  j["angle_deg"] = {{"min", q.min_angle_deg}, {"max", q.max_angle_deg}};
  j["valence"] = {{"histogram", q.valence_histogram},
                  {"share_6", q.valence6_share},
                  {"share_below_5_or_above_7", q.valence_outside_5_7_share}};
  j["edge_length_mean"] = q.edge_length_mean;
  j["crease_share_20"] = q.crease_share_20;
  j["creases"] = {{"angle_deg", 20}, {"interior_edges", q.interior_edges}, {"creased_edges", q.creased_edges_20}};
  if (q.has_sizing)
    j["edge_over_h"] = {{"max", q.edge_h_max}, {"mean", q.edge_h_mean}, {"share_le_2", q.edge_le_2h_share}};
  if (q.has_field)
    j["distance_to_surface"] = {{"vertex_max", q.dist_vertex_max},
                                {"vertex_mean", q.dist_vertex_mean},
                                {"centroid_max", q.dist_centroid_max},
                                {"centroid_mean", q.dist_centroid_mean},
                                {"not_projected", q.dist_failed}};
  const MeshTopology& t = q.topology;
  j["topology"] = {{"watertight", t.boundary_edges == 0},
                   {"manifold", t.nonmanifold_edges == 0 && t.nonmanifold_vertices == 0},
                   {"boundary_edges", t.boundary_edges},
                   {"nonmanifold_edges", t.nonmanifold_edges},
                   {"nonmanifold_vertices", t.nonmanifold_vertices},
                   {"components", t.components},
                   {"euler", t.euler},
                   {"genus", t.genus}};
  if (q.self_intersecting_pairs >= 0) j["self_intersecting_pairs"] = q.self_intersecting_pairs;
  else j["self_intersecting_pairs"] = nullptr;
  return j;
}

std::vector<std::string> check_requirements(const MeshQuality& q, const std::string& req, const QuadQuality* quads) {
  std::vector<std::string> failed;
  std::stringstream ss(req);
  std::string item;
  const MeshTopology& t = q.topology;
  while (std::getline(ss, item, ',')) {
    item.erase(std::remove_if(item.begin(), item.end(), ::isspace), item.end());
    if (item.empty()) continue;
    bool ok = true;
    if (item == "watertight") ok = t.boundary_edges == 0;
    else if (item == "manifold") ok = t.nonmanifold_edges == 0 && t.nonmanifold_vertices == 0;
    else if (item == "no_self_intersections") ok = q.self_intersecting_pairs == 0;
    else {
      std::size_t op = item.find_first_of("<>=");
      if (op == std::string::npos)
        throw UsageError("requirement \"" + item +
                         "\" is unknown; expected watertight, manifold, no_self_intersections or KEY>=V, KEY<=V, "
                         "KEY=V with KEY in rr_min rr_mean min_angle valence6 valence_outside_5_7 edge_le_2h crease_share_20 "
                         "dist_vertex_max dist_centroid_max genus components (polygon meshes: quad_share "
                         "corner_share_70_110 valence4_share jacobian_min)");
      const std::string key = item.substr(0, op);
      std::string cmp = item.substr(op, item[op + 1] == '=' ? 2 : 1);
      double value = 0;
      try {
        value = std::stod(item.substr(op + cmp.size()));
      } catch (const std::exception&) {
        throw UsageError("requirement \"" + item + "\": expected a number after " + cmp);
      }
      double have = 0;
      if (key == "rr_min") have = q.rr_min;
      else if (key == "rr_mean") have = q.rr_mean;
      else if (key == "min_angle") have = q.min_angle_deg;
      else if (key == "valence6") have = q.valence6_share;
      else if (key == "valence_outside_5_7") have = q.valence_outside_5_7_share;
      else if (key == "edge_le_2h") have = q.edge_le_2h_share;
      else if (key == "crease_share_20") have = q.crease_share_20;
      else if (key == "dist_vertex_max") have = q.dist_vertex_max;
      else if (key == "dist_centroid_max") have = q.dist_centroid_max;
      else if (key == "genus") have = double(t.genus);
      else if (key == "components") have = double(t.components);
      else if (key == "quad_share" || key == "corner_share_70_110" || key == "valence4_share" || key == "jacobian_min") {
        if (!quads)
          throw UsageError("requirement \"" + item + "\": " + key + " needs a polygon mesh with quads (.ply .obj .off)");
        have = key == "quad_share"            ? quads->quad_share()
               : key == "corner_share_70_110" ? quads->corner_share_70_110()
               : key == "valence4_share"      ? quads->valence4_share()
                                              : quads->jacobian_min;
      }
      else throw UsageError("requirement \"" + item + "\": unknown key \"" + key + "\"");
      if (cmp == ">=") ok = have >= value;
      else if (cmp == "<=") ok = have <= value;
      else if (cmp == "=" || cmp == "==") ok = have == value;
      else if (cmp == ">") ok = have > value;
      else if (cmp == "<") ok = have < value;
      else throw UsageError("requirement \"" + item + "\": unknown comparison " + cmp);
      if (!ok) {
        std::ostringstream m;
        m << item << " (have " << have << ")";
        failed.push_back(m.str());
        continue;
      }
    }
    if (!ok) failed.push_back(item);
  }
  return failed;
}

}  // namespace pm
