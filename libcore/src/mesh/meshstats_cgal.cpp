// All CGAL includes for meshstats live here: they compile slowly.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <iterator>

#include "pm/base/parallel.h"
#include "pm/mesh/meshstats.h"
#include "pm/mesh/topology.h"

namespace pm {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SM = CGAL::Surface_mesh<K::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;

// m as a CGAL surface mesh whose faces keep m's order; false when it is not a
// manifold polygon mesh (unless the caller knows it is one).
bool to_surface_mesh(const Mesh& m, bool known_polygon_mesh, SM& sm) {
  std::vector<K::Point_3> pts;
  pts.reserve(m.vertices.size());
  for (const Vec3& v : m.vertices) pts.emplace_back(v.x, v.y, v.z);
  std::vector<std::array<std::size_t, 3>> polys;  // fixed-size polygons: no allocation per face
  polys.reserve(m.faces.size());
  for (const auto& f : m.faces) polys.push_back({std::size_t(f[0]), std::size_t(f[1]), std::size_t(f[2])});
  // CGAL's soup test costs more than the intersection test itself on a large
  // mesh; a closed, consistently oriented manifold passes it by construction.
  if (!known_polygon_mesh && !closed_oriented_manifold(m) && !PMP::is_polygon_soup_a_polygon_mesh(polys)) return false;
  PMP::polygon_soup_to_polygon_mesh(pts, polys, sm);  // faces keep the soup's order
  return true;
}

// The grid search's limits (self_intersecting_faces): grid entries per face
// on average, and faces in one cell (pairs tested there: its square).
constexpr std::uint64_t kGridEntriesPerFace = 16;
constexpr std::size_t kGridCellCrowd = 512;

// Found on several threads: each pair as (lower, higher), sorted, so that the
// list does not depend on the thread count.
void normalise(std::vector<std::pair<int, int>>& out) {
  for (auto& [a, b] : out)
    if (b < a) std::swap(a, b);
  std::sort(out.begin(), out.end());
}

}  // namespace

// PMP::self_intersections, with its candidate search done on a grid: the
// same pairs. CGAL reports every collinear (degenerate) face f as (f, f) and
// gives it no box; every other face gets the bounding box of its corners, and
// every pair of faces whose closed boxes meet is tested by do_faces_intersect
// (a real intersection, not a shared vertex or edge). Its box search (a
// segment tree after a random shuffle, partly serial) cost about three times
// the tests on our surfaces. Here each box goes into the grid cells it
// covers, and a pair of meeting boxes is taken in one cell only: the one
// holding the low corner of their intersection, which both boxes cover. The
// cells and the tests run in parallel.
bool self_intersecting_faces(const Mesh& m, std::vector<std::pair<int, int>>& out, bool known_polygon_mesh) {
  out.clear();
  SM sm;
  if (!to_surface_mesh(m, known_polygon_mesh, sm)) return false;
  using face_descriptor = SM::Face_index;
  const std::size_t nf = sm.number_of_faces();
  if (nf == 0) return true;
  const auto vpm = get(CGAL::vertex_point, sm);
  std::vector<CGAL::Bbox_3> box(nf);
  std::vector<char> degenerate(nf, 0);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, nf, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t f = r.begin(); f != r.end(); ++f) {
      const auto h = sm.halfedge(face_descriptor(std::uint32_t(f)));
      const K::Point_3 &p = get(vpm, sm.target(h)), &q = get(vpm, sm.target(sm.next(h))),
                       &s = get(vpm, sm.target(sm.prev(h)));
      degenerate[f] = CGAL::collinear(p, q, s) ? 1 : 0;
      box[f] = p.bbox() + q.bbox() + s.bbox();
    }
  });
  for (std::size_t f = 0; f < nf; ++f)
    if (degenerate[f]) out.emplace_back(int(f), int(f));

  // The grid: cells as wide as the boxes' largest extents on average (most
  // boxes then cover one or two cells per axis), widened until there are at
  // most about four cells per face.
  double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL}, ext = 0;
  std::size_t nb = 0;
  for (std::size_t f = 0; f < nf; ++f) {
    if (degenerate[f]) continue;
    ++nb;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], box[f].min(a));
      hi[a] = std::max(hi[a], box[f].max(a));
    }
    ext += std::max({box[f].xmax() - box[f].xmin(), box[f].ymax() - box[f].ymin(), box[f].zmax() - box[f].zmin()});
  }
  if (nb == 0) {
    normalise(out);
    return true;
  }
  const double span = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  if (!std::isfinite(span) || !std::isfinite(ext)) return detail::cgal_self_intersecting_faces(m, out);
  double w = std::max(ext / double(nb), span * 1e-6);  // at most a million cells along an axis to start
  if (!(w > 0)) w = 1;                                  // every box the same point
  long n[3];
  for (;;) {
    double cells = 1;
    for (int a = 0; a < 3; ++a) {
      n[a] = long(std::floor((hi[a] - lo[a]) / w)) + 1;
      cells *= double(n[a]);
    }
    if (cells <= 4.0 * double(nb) + 64) break;
    w *= 1.25;
  }
  auto cell = [&](double v, int a) {
    const double t = std::floor((v - lo[a]) / w);
    return t < 0 ? 0L : t >= double(n[a] - 1) ? n[a] - 1 : long(t);
  };
  auto cell_id = [&](long i, long j, long k) { return std::uint64_t(i + n[0] * (j + n[1] * k)); };
  // (cell << 32 | face) for every cell a box covers, sorted: the faces of a cell together.
  std::vector<std::uint64_t> count(nf + 1, 0);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, nf, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t f = r.begin(); f != r.end(); ++f) {
      if (degenerate[f]) continue;
      std::uint64_t c = 1;
      for (int a = 0; a < 3; ++a) c *= std::uint64_t(cell(box[f].max(a), a) - cell(box[f].min(a), a) + 1);
      count[f + 1] = c;
    }
  });
  for (std::size_t f = 0; f < nf; ++f) count[f + 1] += count[f];
  // Faces of very different sizes (a few huge ones among many small ones)
  // would fill the grid or crowd single cells: CGAL's own search then.
  if (count[nf] > kGridEntriesPerFace * nb + 1024) return detail::cgal_self_intersecting_faces(m, out);
  std::vector<std::uint64_t> entry(count[nf]);
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, nf, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t f = r.begin(); f != r.end(); ++f) {
      if (degenerate[f]) continue;
      std::uint64_t at = count[f];
      const long i0 = cell(box[f].xmin(), 0), i1 = cell(box[f].xmax(), 0), j0 = cell(box[f].ymin(), 1),
                 j1 = cell(box[f].ymax(), 1), k0 = cell(box[f].zmin(), 2), k1 = cell(box[f].zmax(), 2);
      for (long k = k0; k <= k1; ++k)
        for (long j = j0; j <= j1; ++j)
          for (long i = i0; i <= i1; ++i) entry[at++] = cell_id(i, j, k) << 32 | std::uint64_t(f);
    }
  });
  tbb::parallel_sort(entry.begin(), entry.end());
  std::vector<std::size_t> group;  // starts of the cells' runs
  for (std::size_t e = 0; e < entry.size(); ++e)
    if (e == 0 || entry[e] >> 32 != entry[e - 1] >> 32) {
      if (!group.empty() && e - group.back() > kGridCellCrowd) return detail::cgal_self_intersecting_faces(m, out);
      group.push_back(e);
    }
  if (!group.empty() && entry.size() - group.back() > kGridCellCrowd)
    return detail::cgal_self_intersecting_faces(m, out);
  group.push_back(entry.size());

  const K gt;
  tbb::enumerable_thread_specific<std::vector<std::pair<int, int>>> found;
  pm::parallel_for(tbb::blocked_range<std::size_t>(0, group.size() - 1, 256),
                   [&](const tbb::blocked_range<std::size_t>& r) {
                     auto& mine = found.local();
                     const auto segment = gt.construct_segment_3_object();
                     const auto triangle = gt.construct_triangle_3_object();
                     const auto meet = gt.do_intersect_3_object();
                     for (std::size_t g = r.begin(); g != r.end(); ++g) {
                       const std::uint64_t here = entry[group[g]] >> 32;
                       for (std::size_t x = group[g]; x < group[g + 1]; ++x) {
                         const std::size_t a = std::size_t(entry[x] & 0xffffffffu);
                         for (std::size_t y = x + 1; y < group[g + 1]; ++y) {
                           const std::size_t b = std::size_t(entry[y] & 0xffffffffu);
                           // Closed boxes meet: the low corner of their intersection.
                           double c[3];
                           bool meets = true;
                           for (int t = 0; t < 3 && meets; ++t) {
                             c[t] = std::max(box[a].min(t), box[b].min(t));
                             meets = c[t] <= std::min(box[a].max(t), box[b].max(t));
                           }
                           if (!meets || cell_id(cell(c[0], 0), cell(c[1], 1), cell(c[2], 2)) != here) continue;
                           const auto ha = sm.halfedge(face_descriptor(std::uint32_t(a)));
                           const auto hb = sm.halfedge(face_descriptor(std::uint32_t(b)));
                           if (PMP::internal::do_faces_intersect<K>(ha, hb, sm, vpm, segment, triangle, meet))
                             mine.emplace_back(int(a), int(b));
                         }
                       }
                     }
                   });
  for (const auto& v : found) out.insert(out.end(), v.begin(), v.end());
  normalise(out);
  return true;
}

namespace detail {
bool cgal_self_intersecting_faces(const Mesh& m, std::vector<std::pair<int, int>>& out) {
  out.clear();
  SM sm;
  if (!to_surface_mesh(m, false, sm)) return false;
  std::vector<std::pair<SM::Face_index, SM::Face_index>> pairs;
  PMP::self_intersections<CGAL::Parallel_if_available_tag>(sm, std::back_inserter(pairs));
  for (const auto& p : pairs) out.emplace_back(int(std::size_t(p.first)), int(std::size_t(p.second)));
  normalise(out);
  return true;
}
}  // namespace detail

int count_self_intersections(const Mesh& m) {
  std::vector<std::pair<int, int>> pairs;
  if (!self_intersecting_faces(m, pairs)) return -1;
  return int(pairs.size());
}

std::vector<std::pair<int, int>> material_self_intersections(const Mesh& m, const std::vector<int>& materials,
                                                             std::vector<int>* untested) {
  std::vector<std::pair<int, int>> all, pairs;
  const auto& la = m.face_ints.at("label_a");
  const auto& lb = m.face_ints.at("label_b");
  for (int L : materials) {
    Mesh sub;
    sub.vertices = m.vertices;
    std::vector<int> back;
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
      if (la[f] == L) sub.faces.push_back(m.faces[f]);
      else if (lb[f] == L) sub.faces.push_back({m.faces[f][0], m.faces[f][2], m.faces[f][1]});
      else continue;
      back.push_back(int(f));
    }
    if (sub.faces.empty()) continue;
    if (!self_intersecting_faces(sub, pairs)) {
      if (untested) untested->push_back(L);
      continue;
    }
    for (const auto& [x, y] : pairs) all.emplace_back(back[std::size_t(x)], back[std::size_t(y)]);
  }
  std::sort(all.begin(), all.end());
  all.erase(std::unique(all.begin(), all.end()), all.end());
  return all;
}

}  // namespace pm
