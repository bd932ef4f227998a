#pragma once
// Internal to libcore/src/io: VTK cells (legacy or XML, already decoded) to a
// LabelledTets, shared by read_vtk_tets (vtk.cpp) and read_vtu (vtu.cpp).
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "pm/base/error.h"
#include "pm/io/tet_mesh.h"

namespace pm::vtk_cells {

/// Cell types by what the readers do with them.
inline bool is_tet(int type) { return type == 10 || type == 24 || type == 71; }       // tetra, quadratic, Lagrange
inline bool is_triangle(int type) { return type == 5 || type == 22 || type == 69; }  // likewise
inline bool is_other_3d(int type) {
  switch (type) {
    case 11: case 12: case 13: case 14: case 15: case 16: case 25: case 26: case 27: case 29: case 32: case 33:
    case 42: case 72: case 73: case 74: case 79: case 80: case 81: case 82:
      return true;
    default:
      return false;
  }
}
inline const char* type_name(int type) {
  switch (type) {
    case 11: return "voxel";
    case 12: return "hexahedron";
    case 13: return "wedge";
    case 14: return "pyramid";
    case 42: return "polyhedron";
    default: return "3-D cell";
  }
}

/// Decoded cells: cell c has the vertices conn[begin[c] .. begin[c+1]) and type types[c].
struct Cells {
  std::vector<double> conn;        ///< vertex indices (0-based)
  std::vector<std::size_t> begin;  ///< #cells + 1
  std::vector<int> types;          ///< #cells
};

/// The first of the material array names present in `arrays`, or nullptr.
inline const std::vector<double>* material_array(const std::map<std::string, std::vector<double>>& arrays,
                                                 std::string* name = nullptr) {
  for (const char* n : {"material", "gmsh:physical", "medit:ref"})
    if (auto it = arrays.find(n); it != arrays.end()) {
      if (name) *name = n;
      return &it->second;
    }
  return nullptr;
}

/// Tetrahedra and triangles of `cells` with their materials / label pairs
/// (see read_vtk_tets). `arrays`: cell arrays of one component, #cells values.
/// \throw InputError "<where>: ..." for bad cells, indices or values.
inline LabelledTets to_tets(std::vector<Vec3> points, const Cells& cells,
                            const std::map<std::string, std::vector<double>>& arrays, const std::string& where) {
  const std::size_t n = cells.types.size();
  std::string mat_name;
  const std::vector<double>* mat = material_array(arrays, &mat_name);
  const auto ia = arrays.find("label_a"), ib = arrays.find("label_b");
  const bool pairs = ia != arrays.end() && ib != arrays.end();
  for (const auto& [name, v] : arrays)
    if (v.size() != n)
      throw InputError(where + ": cell array " + quote(name) + " has " + std::to_string(v.size()) +
                       " values; expected one per cell (" + std::to_string(n) + ")");
  auto as_int = [&](const std::string& name, double x, std::size_t c) {
    if (!(std::fabs(x) <= double(std::numeric_limits<int>::max())) || x != std::floor(x))
      throw InputError(where + ": cell array " + quote(name) + ", cell " + std::to_string(c) + ": value " +
                       format_number(x) + " is not an int; expected integer labels");
    return int(x);
  };
  auto vertex = [&](std::size_t c, double x) {
    if (!(x >= 0) || x >= double(points.size()) || x != std::floor(x))
      throw InputError(where + ": cell " + std::to_string(c) + ": vertex " + format_number(x) +
                       " is out of range; expected an integer in [0, " + std::to_string(points.size()) + ")");
    return int(x);
  };
  LabelledTets t;
  for (std::size_t c = 0; c < n; ++c) {
    const int type = cells.types[c];
    const std::size_t b = cells.begin[c], k = cells.begin[c + 1] - b;
    if (is_tet(type)) {
      if (k < 4)
        throw InputError(where + ": cell " + std::to_string(c) + ": a tetrahedron (type " + std::to_string(type) +
                         ") with " + std::to_string(k) + " vertices; expected at least 4");
      for (std::size_t j = 4; j < k; ++j) vertex(c, cells.conn[b + j]);
      t.tets.push_back({vertex(c, cells.conn[b]), vertex(c, cells.conn[b + 1]), vertex(c, cells.conn[b + 2]),
                        vertex(c, cells.conn[b + 3])});
      t.materials.push_back(mat ? as_int(mat_name, (*mat)[c], c) : 0);
    } else if (is_triangle(type)) {
      if (k < 3)
        throw InputError(where + ": cell " + std::to_string(c) + ": a triangle (type " + std::to_string(type) +
                         ") with " + std::to_string(k) + " vertices; expected at least 3");
      t.triangles.push_back({vertex(c, cells.conn[b]), vertex(c, cells.conn[b + 1]), vertex(c, cells.conn[b + 2])});
      if (pairs) {
        const int a = as_int("label_a", ia->second[c], c), bb = as_int("label_b", ib->second[c], c);
        t.triangle_labels.push_back({std::min(a, bb), std::max(a, bb)});
      } else {
        t.triangle_labels.push_back({0, mat ? as_int(mat_name, (*mat)[c], c) : 0});
      }
    } else if (is_other_3d(type)) {
      throw InputError(where + ": cell " + std::to_string(c) + " is a " + type_name(type) + " (VTK type " +
                       std::to_string(type) + "); expected tetrahedra only (type 10)");
    }
  }
  t.vertices = std::move(points);
  t.validate(where);
  return t;
}

}  // namespace pm::vtk_cells
