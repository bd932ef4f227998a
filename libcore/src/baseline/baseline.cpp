// Marching-cubes baseline (OpenVDB's volumeToMesh, in the plugin: see
// marching_cubes_openvdb.cpp) and the label-map triple lines used by the CGAL
// baseline (baseline_cgal.cpp holds every CGAL include).
#include "pm/baseline/baseline.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/base/log.h"
#include "../io/openvdb_plugin.h"

namespace pm {

namespace {

double signed_volume(const Mesh& m) {
  double s = 0;
  for (const auto& f : m.faces)
    s += dot(m.vertices[std::size_t(f[0])], cross(m.vertices[std::size_t(f[1])], m.vertices[std::size_t(f[2])]));
  return s / 6;
}

}  // namespace

double mesh_area(const Mesh& m) {
  double a = 0;
  for (const auto& f : m.faces) {
    const Vec3& p = m.vertices[std::size_t(f[0])];
    a += 0.5 * norm(cross(m.vertices[std::size_t(f[1])] - p, m.vertices[std::size_t(f[2])] - p));
  }
  return a;
}

double facet_size_for_vertices(double area, std::size_t vertices) {
  if (!(area > 0) || vertices == 0)
    throw UsageError("facet_size_for_vertices: need a positive area and vertex count, got area " +
                     std::to_string(area) + " and " + std::to_string(vertices) + " vertices");
  const double edge = std::sqrt(2 * area / (std::sqrt(3.0) * double(vertices)));
  return edge / 1.2;
}

double label_interface_area(const Volume& v, const std::string& what) {
  const Dims d = v.dims();
  const double sp[3] = {v.geometry().spacing(0), v.geometry().spacing(1), v.geometry().spacing(2)};
  const std::size_t step[3] = {1, d.nx, d.nx * d.ny};
  double area = 0;
  for (std::size_t k = 0; k < d.nz; ++k)
    for (std::size_t j = 0; j < d.ny; ++j)
      for (std::size_t i = 0; i < d.nx; ++i) {
        const std::size_t idx = v.index(i, j, k);
        const std::size_t ijk[3] = {i, j, k};
        for (int a = 0; a < 3; ++a)
          if (ijk[a] + 1 < d[a] && v.get(idx) != v.get(idx + step[a])) area += sp[(a + 1) % 3] * sp[(a + 2) % 3];
      }
  if (area == 0) throw InputError(quote(what) + ": a single label; expected a label map with at least two labels");
  return area * 2 / 3;
}

namespace {
// The search's secant exponent stays within these multiples of the model's
// (SizeSearchParams::exponent): a noisy pair of runs cannot send it far.
constexpr double kSecantExponentMin = 0.5, kSecantExponentMax = 4.0;
}  // namespace

SizeSearchResult cgal_size_search(const CgalMesher& mesher, CgalMeshParams p, const SizeSearchParams& s) {
  SizeSearchResult out;
  if (s.target == 0) {
    out.best = mesher(p);
    out.facet_size = p.facet_size;
    return out;
  }
  if (!(s.start_size > 0)) throw UsageError("cgal_size_search: start size must be > 0 world units");
  // Volume meshes: the size is searched without sliver optimisation (it
  // moves vertices but adds none), then the best size is run once with it.
  const bool optimise_last = p.volume && p.optimise;
  p.optimise = false;
  p.facet_size = s.start_size;
  double best_err = 1e300;
  for (int k = 0; k < std::max(1, s.max_runs); ++k) {
    CgalMeshResult r = mesher(p);
    const double n = double(r.vertex_count());
    const double err = std::abs(n / double(s.target) - 1);
    out.tries.push_back({p.facet_size, r.vertex_count(), r.seconds});
    info("facet size " + std::to_string(p.facet_size) + ": " + std::to_string(r.vertex_count()) +
         " vertices (target " + std::to_string(s.target) + ")");
    if (err < best_err) {
      best_err = err;
      out.best = std::move(r);
      out.facet_size = p.facet_size;
    }
    if (err <= s.tolerance || n == 0) break;
    // After two runs the exponent is the log-log secant of the last two:
    // counts that include size-independent vertices (features, facet
    // distance) fall slower than the model's power (the nested head:
    // N ~ size^-0.94, where the fixed 0.5 needed five runs to come 11% off).
    double exponent = s.exponent;
    if (out.tries.size() >= 2) {
      const SizeSearchTry& a = out.tries[out.tries.size() - 2];
      const SizeSearchTry& b = out.tries.back();
      const double dn = std::log(double(std::max<std::size_t>(a.vertices, 1)) / double(b.vertices));
      const double ds = std::log(b.facet_size / a.facet_size);
      if (ds != 0 && dn != 0 && std::isfinite(dn / ds))
        exponent = std::clamp(ds / dn, kSecantExponentMin * s.exponent, kSecantExponentMax * s.exponent);
    }
    p.facet_size *= std::pow(n / double(s.target), exponent);
  }
  out.deviation = best_err;
  if (optimise_last) {
    p.optimise = true;
    p.facet_size = out.facet_size;
    out.best = mesher(p);
    out.deviation = std::abs(double(out.best.vertex_count()) / double(s.target) - 1);
  }
  return out;
}

Mesh marching_cubes_baseline(const Volume& v, double iso, bool material_below) {
  Mesh out = openvdb_plugin().marching_cubes(v, iso, material_below);
  if (out.faces.empty())
    throw InputError("marching cubes: no triangle at F = " + std::to_string(iso) + "; expected a surface");
  if (signed_volume(out) < 0)
    for (auto& f : out.faces) std::swap(f[1], f[2]);
  return out;
}

std::vector<std::vector<Vec3>> triple_lines(const Volume& labels) {
  const Dims d = labels.dims();
  const std::size_t nx = d.nx, ny = d.ny, nz = d.nz;
  if (nx < 2 || ny < 2 || nz < 2) return {};
  const std::size_t step[3] = {1, nx, nx * ny};
  auto lab = [&](std::size_t idx) { return std::int64_t(labels.get(idx)); };
  auto distinct = [](std::int64_t* a, int n) {
    std::sort(a, a + n);
    return int(std::unique(a, a + n) - a);
  };
  // Square with normal axis a whose lowest voxel is idx: at least three labels?
  auto square_is_junction = [&](int a, std::size_t idx) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    std::int64_t l[4] = {lab(idx), lab(idx + step[b]), lab(idx + step[c]), lab(idx + step[b] + step[c])};
    return distinct(l, 4) >= 3;
  };
  const Geometry& geo = labels.geometry();
  std::unordered_map<std::uint64_t, int> node_of;
  std::vector<Vec3> nodes;
  std::set<std::pair<int, int>> edges;
  auto node = [&](std::uint64_t key, const Vec3& ijk) {
    auto it = node_of.find(key);
    if (it != node_of.end()) return it->second;
    nodes.push_back(geo.index_to_world(ijk));
    node_of.emplace(key, int(nodes.size()) - 1);
    return int(nodes.size()) - 1;
  };
  auto add_edge = [&](int u, int w) {
    if (u != w) edges.insert({std::min(u, w), std::max(u, w)});
  };
  const std::uint64_t n = labels.count();
  for (std::size_t k = 0; k + 1 < nz; ++k)
    for (std::size_t j = 0; j + 1 < ny; ++j)
      for (std::size_t i = 0; i + 1 < nx; ++i) {
        const std::size_t idx = labels.index(i, j, k);
        std::int64_t l[8];
        for (int c = 0; c < 8; ++c)
          l[c] = lab(idx + ((c & 1) ? step[0] : 0) + ((c & 2) ? step[1] : 0) + ((c & 4) ? step[2] : 0));
        if (distinct(l, 8) < 3) continue;
        int faces[6];
        int nf = 0;
        for (int a = 0; a < 3; ++a)
          for (int up = 0; up < 2; ++up) {
            const std::size_t base = idx + (up ? step[a] : 0);
            if (!square_is_junction(a, base)) continue;
            Vec3 ijk{double(i), double(j), double(k)};
            ijk[a] += up;
            ijk[(a + 1) % 3] += 0.5;
            ijk[(a + 2) % 3] += 0.5;
            faces[nf++] = node(std::uint64_t(a) * n + base, ijk);
          }
        if (nf == 2) {
          add_edge(faces[0], faces[1]);
        } else if (nf > 0) {
          const int centre = node(3 * n + idx, Vec3{i + 0.5, j + 0.5, k + 0.5});
          for (int f = 0; f < nf; ++f) add_edge(faces[f], centre);
        }
      }
  // Split the graph into polylines between nodes of degree != 2, then loops.
  std::vector<std::vector<int>> adj(nodes.size());
  for (const auto& e : edges) {
    adj[std::size_t(e.first)].push_back(e.second);
    adj[std::size_t(e.second)].push_back(e.first);
  }
  std::set<std::pair<int, int>> used;
  auto take = [&](int u, int w) { return used.insert({std::min(u, w), std::max(u, w)}).second; };
  std::vector<std::vector<Vec3>> lines;
  auto walk = [&](int start, int next) {
    std::vector<Vec3> line{nodes[std::size_t(start)]};
    int prev = start, cur = next;
    for (;;) {
      line.push_back(nodes[std::size_t(cur)]);
      if (cur == start || adj[std::size_t(cur)].size() != 2) break;
      const int nxt = adj[std::size_t(cur)][0] == prev ? adj[std::size_t(cur)][1] : adj[std::size_t(cur)][0];
      if (!take(cur, nxt)) break;
      prev = cur;
      cur = nxt;
    }
    lines.push_back(std::move(line));
  };
  for (std::size_t u = 0; u < nodes.size(); ++u)
    if (adj[u].size() != 2)
      for (int w : adj[u])
        if (take(int(u), w)) walk(int(u), w);
  for (std::size_t u = 0; u < nodes.size(); ++u)
    for (int w : adj[u])
      if (take(int(u), w)) walk(int(u), w);
  return lines;
}

}  // namespace pm
