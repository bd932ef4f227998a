// Gmsh MSH 4.1 ASCII writer (see pm/io/gmsh.h).
#include "pm/io/gmsh.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <vector>

#include "pm/base/error.h"

namespace pm {

void write_gmsh(const LabelledTets& t, const std::string& path, WorldFrame frame) {
  const std::string where = "write_gmsh: " + quote(path);
  t.validate(where);
  if (t.tets.empty()) throw InputError(where + ": no tetrahedra; expected at least one to write");
  std::map<int, std::vector<std::size_t>> by_label;
  for (std::size_t i = 0; i < t.tets.size(); ++i) by_label[t.materials[i]].push_back(i);
  const bool positive = by_label.begin()->first > 0;
  std::map<int, int> tag;  // label -> physical tag = entity tag
  int k = 0;
  for (const auto& [l, v] : by_label) tag[l] = positive ? l : ++k;

  std::string o;
  char b[96];
  o += "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
  o += std::string("$Comments\nwritten by particlemesh " PM_VERSION ", frame ") + frame_name(frame) +
       " SPACE=" + frame_name(frame) + "\n$EndComments\n";
  o += "$PhysicalNames\n" + std::to_string(by_label.size()) + "\n";
  for (const auto& [l, v] : by_label) o += "3 " + std::to_string(tag[l]) + " \"material_" + std::to_string(l) + "\"\n";
  o += "$EndPhysicalNames\n";
  // Entities: 0 points, 0 curves, 0 surfaces, one volume per material with
  // its bounding box, one physical tag and no bounding surfaces.
  o += "$Entities\n0 0 0 " + std::to_string(by_label.size()) + "\n";
  for (const auto& [l, idx] : by_label) {
    Vec3 lo(1e300, 1e300, 1e300), hi(-1e300, -1e300, -1e300);
    for (std::size_t i : idx)
      for (int v : t.tets[i])
        for (int c = 0; c < 3; ++c) {
          lo[c] = std::min(lo[c], t.vertices[std::size_t(v)][c]);
          hi[c] = std::max(hi[c], t.vertices[std::size_t(v)][c]);
        }
    std::snprintf(b, sizeof b, "%d %.17g %.17g %.17g ", tag[l], lo.x, lo.y, lo.z);
    o += b;
    std::snprintf(b, sizeof b, "%.17g %.17g %.17g 1 %d 0\n", hi.x, hi.y, hi.z, tag[l]);
    o += b;
  }
  o += "$EndEntities\n";
  const std::size_t nv = t.vertices.size();
  const int first = tag.begin()->second;
  o += "$Nodes\n1 " + std::to_string(nv) + " 1 " + std::to_string(nv) + "\n";
  o += "3 " + std::to_string(first) + " 0 " + std::to_string(nv) + "\n";
  for (std::size_t i = 0; i < nv; ++i) o += std::to_string(i + 1) + "\n";
  for (const Vec3& p : t.vertices) {
    std::snprintf(b, sizeof b, "%.17g %.17g %.17g\n", p.x, p.y, p.z);
    o += b;
  }
  o += "$EndNodes\n";
  o += "$Elements\n" + std::to_string(by_label.size()) + " " + std::to_string(t.tets.size()) + " 1 " +
       std::to_string(t.tets.size()) + "\n";
  std::size_t id = 0;
  for (const auto& [l, idx] : by_label) {
    o += "3 " + std::to_string(tag[l]) + " 4 " + std::to_string(idx.size()) + "\n";
    for (std::size_t i : idx) {
      const auto& c = t.tets[i];
      o += std::to_string(++id) + " " + std::to_string(c[0] + 1) + " " + std::to_string(c[1] + 1) + " " +
           std::to_string(c[2] + 1) + " " + std::to_string(c[3] + 1) + "\n";
    }
  }
  o += "$EndElements\n";
  std::ofstream os(path, std::ios::binary);
  if (!os) throw IoError(where + ": cannot open for writing");
  os.write(o.data(), std::streamsize(o.size()));
  os.close();
  if (!os) throw IoError(where + ": write failed (disk full?)");
}

}  // namespace pm
