#include "pm/io/poly_mesh.h"

#include <cstdint>
#include <cstring>
#include <fstream>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/mesh.h"
#include "pm/io/mesh_cgal.h"
#include "pm/io/number_text.h"
#include "pm/io/ply.h"

namespace pm {
namespace {

std::string num(double v) { return number_text(v); }

template <class T>
void put(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));  // little-endian hosts only (x86-64, arm64), as write_ply
}

std::string ply(const PolyMesh& m, const std::vector<Vec3>& x, WorldFrame frame, bool binary) {
  std::string out = "ply\nformat ";
  out += binary ? "binary_little_endian 1.0\n" : "ascii 1.0\n";
  out += "comment written by particlemesh " PM_VERSION " (quad-dominant)\n";
  out += std::string("comment frame ") + frame_name(frame) + " SPACE=" + frame_name(frame) + "\n";
  out += "element vertex " + std::to_string(x.size()) + "\nproperty double x\nproperty double y\nproperty double z\n";
  out += "element face " + std::to_string(m.faces.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const Vec3& v : x) {
    if (binary) {
      put(out, v.x);
      put(out, v.y);
      put(out, v.z);
    } else {
      out += num(v.x) + " " + num(v.y) + " " + num(v.z) + "\n";
    }
  }
  for (const auto& f : m.faces) {
    const int n = f[3] >= 0 ? 4 : 3;
    if (binary) {
      put(out, std::uint8_t(n));
      for (int k = 0; k < n; ++k) put(out, std::int32_t(f[std::size_t(k)]));
    } else {
      out += std::to_string(n);
      for (int k = 0; k < n; ++k) out += " " + std::to_string(f[std::size_t(k)]);
      out += "\n";
    }
  }
  return out;
}

std::string obj(const PolyMesh& m, const std::vector<Vec3>& x, WorldFrame frame) {
  std::string out = "# written by particlemesh " PM_VERSION " (quad-dominant)\n";
  out += std::string("# frame ") + frame_name(frame) + " SPACE=" + frame_name(frame) + "\n";
  for (const Vec3& v : x) out += "v " + num(v.x) + " " + num(v.y) + " " + num(v.z) + "\n";
  for (const auto& f : m.faces) {
    out += "f";
    for (int k = 0; k < (f[3] >= 0 ? 4 : 3); ++k) out += " " + std::to_string(f[std::size_t(k)] + 1);
    out += "\n";
  }
  return out;
}

std::string off(const PolyMesh& m, const std::vector<Vec3>& x) {
  std::string out = "OFF\n" + std::to_string(x.size()) + " " + std::to_string(m.faces.size()) + " 0\n";
  for (const Vec3& v : x) out += num(v.x) + " " + num(v.y) + " " + num(v.z) + "\n";
  for (const auto& f : m.faces) {
    const int n = f[3] >= 0 ? 4 : 3;
    out += std::to_string(n);
    for (int k = 0; k < n; ++k) out += " " + std::to_string(f[std::size_t(k)]);
    out += "\n";
  }
  return out;
}

}  // namespace

bool is_poly_mesh_path(const std::string& path) {
  const std::string e = file_extension(path);
  return e == ".ply" || e == ".obj" || e == ".off";
}

std::string poly_mesh_extensions() { return ".ply .obj .off"; }

PolyMesh fans_to_polygons(const Mesh& tri, const std::vector<int>& polygon_sizes, const std::string& what) {
  PolyMesh p;
  p.vertices = tri.vertices;
  p.faces.reserve(polygon_sizes.size());
  std::size_t t = 0;
  for (std::size_t k = 0; k < polygon_sizes.size(); ++k) {
    const int n = polygon_sizes[k];
    if (n != 3 && n != 4)
      throw InputError(what + ": polygon " + std::to_string(k) + " has " + std::to_string(n) +
                       " vertices; expected triangles and quads");
    if (t + std::size_t(n - 2) > tri.faces.size()) break;
    const auto& a = tri.faces[t];
    if (n == 3) {
      p.faces.push_back({a[0], a[1], a[2], -1});
    } else {
      const auto& b = tri.faces[t + 1];  // the fan (v0 v1 v2), (v0 v2 v3)
      p.faces.push_back({a[0], a[1], a[2], b[2]});
    }
    t += std::size_t(n - 2);
  }
  if (t != tri.faces.size() || p.faces.size() != polygon_sizes.size())
    throw InputError(what + ": " + std::to_string(polygon_sizes.size()) + " polygons do not make the " +
                     std::to_string(tri.faces.size()) + " triangles read");
  p.validate(what);
  return p;
}

PolyMesh read_poly_mesh(const std::string& path, WorldFrame* frame) {
  const std::string ext = file_extension(path);
  std::vector<int> sizes;
  Mesh tri;
  if (frame) *frame = WorldFrame::lps;
  if (ext == ".ply")
    tri = read_ply(path, frame, &sizes);
  else if (ext == ".off")
    tri = read_off(path, &sizes);
  else if (ext == ".obj")
    tri = read_obj(path, &sizes);
  else
    throw UsageError(quote(path) + ": unknown polygon mesh extension; expected " + poly_mesh_extensions());
  return fans_to_polygons(tri, sizes, quote(path));
}

Mesh read_mesh_polygons(const std::string& path, std::vector<int>& polygon_sizes) {
  polygon_sizes.clear();
  if (!is_poly_mesh_path(path)) {
    Mesh m = read_mesh(path);
    polygon_sizes.assign(m.faces.size(), 3);
    return m;
  }
  const std::string ext = file_extension(path);
  WorldFrame frame = WorldFrame::lps;
  Mesh m = ext == ".ply" ? read_ply(path, &frame, &polygon_sizes)
                         : ext == ".off" ? read_off(path, &polygon_sizes) : read_obj(path, &polygon_sizes);
  m.validate("read_mesh: " + quote(path));
  convert_frame(m, frame, WorldFrame::lps);
  return m;
}

void write_poly_mesh(const PolyMesh& m, const std::string& path, WorldFrame frame, bool binary) {
  const std::string e = file_extension(path);
  if (!is_poly_mesh_path(path))
    throw UsageError(quote(path) + ": " + (e.empty() ? std::string("no extension") : "extension " + quote(e)) +
                     (e == ".stl" ? " holds triangles only" : " is not a polygon mesh format") +
                     "; expected " + poly_mesh_extensions() + " for a quad-dominant mesh");
  m.validate(quote(path));
  Mesh pts;
  pts.vertices = m.vertices;
  convert_frame(pts, WorldFrame::lps, frame);
  const std::string text = e == ".ply" ? ply(m, pts.vertices, frame, binary)
                           : e == ".obj" ? obj(m, pts.vertices, frame)
                                         : off(m, pts.vertices);
  write_atomically(path, [&](const std::string& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f.write(text.data(), std::streamsize(text.size()));
    f.close();
    if (!f) throw IoError("cannot write " + quote(path));
  });
}

}  // namespace pm
