// Parallel Delaunay tetrahedralisation with CGAL (Delaunay_triangulation_3
// with Parallel_tag, spatially sorted insertion on TBB's threads), in a
// translation unit of its own: CGAL's headers compile slowly.
#include "delaunay_cgal.h"

#ifdef CGAL_LINKED_WITH_TBB
#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_data_structure_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cstdint>
#endif

namespace pm {

#ifdef CGAL_LINKED_WITH_TBB
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_3<int, K>;
using Cb = CGAL::Triangulation_cell_base_with_info_3<int, K, CGAL::Delaunay_triangulation_cell_base_3<K>>;
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb, CGAL::Parallel_tag>;
using DT = CGAL::Delaunay_triangulation_3<K, Tds>;

// Cells per lock-grid axis: CGAL's examples use 50; the grid only spreads
// the insertion's locks.
constexpr int kLockGrid = 50;

}  // namespace

bool parallel_delaunay(const std::vector<Vec3>& points, TetMesh& out, std::size_t& vertices) {
  std::vector<std::pair<K::Point_3, int>> in(points.size());
  CGAL::Bbox_3 box;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3& p = points[i];
    in[i] = {K::Point_3(p.x, p.y, p.z), int(i)};
    box += in[i].first.bbox();
  }
  DT::Lock_data_structure locks(box, kLockGrid);
  DT dt(in.begin(), in.end(), &locks);
  vertices = dt.number_of_vertices();
  if (vertices != points.size() || dt.dimension() != 3) return true;  // the caller reports it

  // The container's cell order depends on the threads' schedule: number the
  // finite cells, then give every tetrahedron a canonical form (sorted
  // corners, the first two swapped when that orientation is negative) and
  // sort them, so that the mesh depends on the points only.
  std::vector<DT::Cell_handle> cells;
  cells.reserve(dt.number_of_finite_cells());
  for (auto c = dt.finite_cells_begin(); c != dt.finite_cells_end(); ++c) cells.push_back(c);
  const std::size_t nt = cells.size();
  struct Tet {
    std::array<int, 4> key;  // the corners, ascending (the sort key)
    std::array<int, 4> v;    // canonical corners
    std::array<int, 4> slot; // corner k of the canonical form = CGAL's corner slot[k]
    std::uint32_t cell;      // index into cells
  };
  std::vector<Tet> tets(nt);
  tbb::parallel_for(std::size_t(0), nt, [&](std::size_t t) {
    const DT::Cell_handle c = cells[t];
    std::array<int, 4> idx{0, 1, 2, 3};
    std::array<int, 4> v;
    for (int k = 0; k < 4; ++k) v[std::size_t(k)] = c->vertex(k)->info();
    std::sort(idx.begin(), idx.end(), [&](int a, int b) { return v[std::size_t(a)] < v[std::size_t(b)]; });
    Tet T;
    for (int k = 0; k < 4; ++k) {
      T.slot[std::size_t(k)] = idx[std::size_t(k)];
      T.v[std::size_t(k)] = v[std::size_t(idx[std::size_t(k)])];
    }
    T.key = T.v;
    const Vec3 &a = points[std::size_t(T.v[0])], &b = points[std::size_t(T.v[1])], &cc = points[std::size_t(T.v[2])],
               &d = points[std::size_t(T.v[3])];
    if (dot(b - a, cross(cc - a, d - a)) < 0) {
      std::swap(T.v[0], T.v[1]);
      std::swap(T.slot[0], T.slot[1]);
    }
    T.cell = std::uint32_t(t);
    tets[t] = T;
  });
  // Canonical order: by the corners ascending; a counting sort on the
  // smallest corner, then each (small) group by the rest.
  std::vector<std::uint32_t> start(points.size() + 1, 0), order(nt);
  for (const Tet& T : tets) ++start[std::size_t(T.key[0]) + 1];
  for (std::size_t i = 0; i < points.size(); ++i) start[i + 1] += start[i];
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t t = 0; t < nt; ++t) order[fill[std::size_t(tets[t].key[0])]++] = std::uint32_t(t);
  }
  tbb::parallel_for(std::size_t(0), points.size(), [&](std::size_t i) {
    std::sort(order.begin() + start[i], order.begin() + start[i + 1],
              [&](std::uint32_t a, std::uint32_t b) { return tets[a].key < tets[b].key; });
  });
  tbb::parallel_for(std::size_t(0), nt, [&](std::size_t t) { cells[tets[order[t]].cell]->info() = int(t); });
  out.points = points;
  out.tets.resize(nt);
  out.neighbours.resize(nt);
  tbb::parallel_for(std::size_t(0), nt, [&](std::size_t t) {
    const Tet& T = tets[order[t]];
    const DT::Cell_handle c = cells[T.cell];
    out.tets[t] = T.v;
    for (int k = 0; k < 4; ++k) {
      const DT::Cell_handle n = c->neighbor(T.slot[std::size_t(k)]);
      out.neighbours[t][std::size_t(k)] = dt.is_infinite(n) ? -1 : n->info();
    }
  });
  return true;
}
#else
bool parallel_delaunay(const std::vector<Vec3>&, TetMesh&, std::size_t&) { return false; }
#endif

}  // namespace pm
