// VTK legacy and XML writers, the legacy POLYDATA reader and the legacy
// UNSTRUCTURED_GRID tetrahedra reader (see pm/io/vtk.h).
#include "pm/io/vtk.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/number_text.h"
#include "pm/io/ply.h"
#include "scan.h"
#include "vtk_cells.h"

namespace pm {
namespace {

constexpr int kVtkVertex = 1, kVtkTriangle = 5, kVtkPolygon = 7, kVtkTetra = 10;

void save(const std::string& text, const std::string& path, const std::string& where) {
  std::ofstream os(path, std::ios::binary);
  if (!os) throw IoError(where + ": cannot open for writing");
  os.write(text.data(), std::streamsize(text.size()));
  os.close();
  if (!os) throw IoError(where + ": write failed (disk full?)");
}

// Appends values as legacy VTK wants them: ASCII (17 digits for doubles) or
// big-endian binary.
class LegacyOut {
 public:
  LegacyOut(std::string& out, bool binary) : out_(out), binary_(binary) {}
  void f64(double v) {
    if (!binary_) {
      append_number(out_, v);
      out_ += ' ';
      return;
    }
    std::uint64_t u;
    std::memcpy(&u, &v, 8);
    for (int s = 56; s >= 0; s -= 8) out_ += char((u >> s) & 0xff);
  }
  void i32(std::int32_t v) {
    if (!binary_) {
      out_ += std::to_string(v);
      out_ += ' ';
      return;
    }
    const std::uint32_t u = std::uint32_t(v);
    for (int s = 24; s >= 0; s -= 8) out_ += char((u >> s) & 0xff);
  }
  void u8(unsigned v) {
    if (!binary_) {
      out_ += std::to_string(v);
      out_ += ' ';
      return;
    }
    out_ += char(v);
  }
  // End of a record (ASCII) or of a section.
  void eol() {
    if (!binary_) {
      if (!out_.empty() && out_.back() == ' ') out_.back() = '\n';
      else out_ += '\n';
    }
  }
  void end_section() {
    if (binary_) out_ += '\n';
  }

 private:
  std::string& out_;
  bool binary_;
};

std::string legacy_header(const char* dataset, bool binary, WorldFrame frame) {
  return std::string("# vtk DataFile Version 4.2\nparticlemesh " PM_VERSION " SPACE=") + frame_name(frame) +
         "\n" + (binary ? "BINARY\n" : "ASCII\n") + "DATASET " + dataset + "\n";
}

void legacy_points(std::string& out, LegacyOut& o, const std::vector<Vec3>& p) {
  out += "POINTS " + std::to_string(p.size()) + " double\n";
  for (const Vec3& v : p) {
    o.f64(v.x);
    o.f64(v.y);
    o.f64(v.z);
    o.eol();
  }
  o.end_section();
}

void legacy_int_scalars(std::string& out, LegacyOut& o, const std::string& name, const std::vector<int>& v) {
  out += "SCALARS " + name + " int 1\nLOOKUP_TABLE default\n";
  for (int x : v) {
    o.i32(x);
    o.eol();
  }
  o.end_section();
}

// ---- XML ----

std::string xml_escape(const std::string& s) {
  std::string r;
  for (char c : s) {
    if (c == '&') r += "&amp;";
    else if (c == '<') r += "&lt;";
    else if (c == '>') r += "&gt;";
    else if (c == '"') r += "&quot;";
    else r += c;
  }
  return r;
}

// The FieldData string array Slicer reads the frame from (ASCII string arrays
// are character codes, each string ended by 0).
std::string xml_space_field(WorldFrame frame) {
  std::string codes;
  for (const char* c = frame_name(frame); *c; ++c) codes += std::to_string(int(*c)) + " ";
  return "    <FieldData>\n      <Array type=\"String\" Name=\"SPACE\" NumberOfTuples=\"1\" format=\"ascii\">\n        " +
         codes + "0\n      </Array>\n    </FieldData>\n";
}

void xml_open_array(std::string& out, const char* type, const std::string& name, int components) {
  out += "        <DataArray type=\"";
  out += type;
  out += "\"";
  if (!name.empty()) out += " Name=\"" + xml_escape(name) + "\"";
  if (components > 1) out += " NumberOfComponents=\"" + std::to_string(components) + "\"";
  out += " format=\"ascii\">\n";
}
void xml_close_array(std::string& out) { out += "\n        </DataArray>\n"; }

void xml_f64(std::string& out, double v) {
  append_number(out, v);
  out += ' ';
}

void xml_vec3s(std::string& out, const char* name, const std::vector<Vec3>& v) {
  xml_open_array(out, "Float64", name, 3);
  for (std::size_t i = 0; i < v.size(); ++i) {
    xml_f64(out, v[i].x);
    xml_f64(out, v[i].y);
    xml_f64(out, v[i].z);
    if (i % 4 == 3) out += '\n';
  }
  xml_close_array(out);
}

template <class T>
void xml_ints(std::string& out, const char* type, const std::string& name, const std::vector<T>& v) {
  xml_open_array(out, type, name, 1);
  for (std::size_t i = 0; i < v.size(); ++i) {
    out += std::to_string(v[i]);
    out += i % 16 == 15 ? '\n' : ' ';
  }
  xml_close_array(out);
}

// `space_field`: the FieldData array SPACE that Slicer reads. meshio's VTU
// reader refuses String arrays (ReadError "Illegal data type"), so .vtu files
// state the frame in the comment only.
std::string xml_head(const char* type, WorldFrame frame, bool space_field) {
  return std::string("<?xml version=\"1.0\"?>\n<!-- written by particlemesh " PM_VERSION ", frame ") +
         frame_name(frame) + " SPACE=" + frame_name(frame) + " -->\n<VTKFile type=\"" + type +
         "\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n  <" + type + ">\n" +
         (space_field ? xml_space_field(frame) : std::string());
}

void xml_point_data(std::string& out, const Mesh& m) {
  if (!m.has_normals() && m.vertex_scalars.empty()) return;
  out += m.has_normals() ? "      <PointData Normals=\"Normals\">\n" : "      <PointData>\n";
  if (m.has_normals()) xml_vec3s(out, "Normals", m.normals);
  for (const auto& [name, v] : m.vertex_scalars) {
    xml_open_array(out, "Float64", name, 1);
    for (std::size_t i = 0; i < v.size(); ++i) {
      xml_f64(out, v[i]);
      if (i % 8 == 7) out += '\n';
    }
    xml_close_array(out);
  }
  out += "      </PointData>\n";
}

// ---- legacy reader ----

class LegacyIn {
 public:
  LegacyIn(std::string data, std::string where) : d_(std::move(data)), where_(std::move(where)) {}

  [[noreturn]] void fail(const std::string& what) const { throw InputError(where_ + ": " + what); }

  bool at_end() {
    skip_space();
    return p_ >= d_.size();
  }
  // One header line (without the newline).
  std::string line() {
    if (p_ >= d_.size()) fail("unexpected end of file in the header; expected 4 header lines");
    std::size_t e = d_.find('\n', p_);
    if (e == std::string::npos) e = d_.size();
    std::string l = d_.substr(p_, e - p_);
    if (!l.empty() && l.back() == '\r') l.pop_back();
    p_ = std::min(d_.size(), e + 1);
    return l;
  }
  std::string word() {
    skip_space();
    const std::size_t b = p_;
    while (p_ < d_.size() && !std::isspace(static_cast<unsigned char>(d_[p_]))) ++p_;
    return d_.substr(b, p_ - b);
  }
  std::uint64_t count(const std::string& what) {
    const std::string w = word();
    if (w.empty() || w.size() > 18 || !std::all_of(w.begin(), w.end(), [](char c) { return c >= '0' && c <= '9'; }))
      fail(what + ": " + quote(w) + " is not a count; expected a non-negative integer");
    return std::stoull(w);
  }
  // The rest of the current line, trimmed; moves to the next line.
  std::string rest() {
    std::size_t e = d_.find('\n', p_);
    if (e == std::string::npos) e = d_.size();
    std::string r = d_.substr(p_, e - p_);
    p_ = std::min(d_.size(), e + 1);
    while (!r.empty() && std::isspace(static_cast<unsigned char>(r.back()))) r.pop_back();
    while (!r.empty() && std::isspace(static_cast<unsigned char>(r.front()))) r.erase(0, 1);
    return r;
  }
  // Skip to the start of the next line (after a section keyword line).
  void next_line() {
    while (p_ < d_.size() && d_[p_] != '\n') ++p_;
    if (p_ < d_.size()) ++p_;
  }
  std::size_t remaining() const { return d_.size() - p_; }

  double f64(bool binary, const std::string& type, const std::string& what) {
    if (!binary) {
      skip_space();
      if (p_ >= d_.size()) fail(what + ": unexpected end of data (truncated file?)");
      char* end = nullptr;
      const double v = std::strtod(d_.c_str() + p_, &end);
      const std::size_t e = std::size_t(end - d_.c_str());
      if (e == p_ || (e < d_.size() && !std::isspace(static_cast<unsigned char>(d_[e]))))
        fail(what + ": " + quote(d_.substr(p_, std::min<std::size_t>(20, d_.size() - p_))) +
             " is not a number");
      p_ = e;
      return v;
    }
    const int n = type == "double" ? 8 : (type == "float" || type == "int" || type == "unsigned_int") ? 4 : 0;
    if (n == 0 && type != "unsigned_char" && type != "char") fail(what + ": unsupported type " + quote(type));
    const int bytes = n == 0 ? 1 : n;
    if (remaining() < std::size_t(bytes)) fail(what + ": unexpected end of binary data (truncated file?)");
    std::uint64_t u = 0;
    for (int k = 0; k < bytes; ++k) u = (u << 8) | static_cast<unsigned char>(d_[p_ + std::size_t(k)]);
    p_ += std::size_t(bytes);
    if (type == "double") {
      double v;
      std::memcpy(&v, &u, 8);
      return v;
    }
    if (type == "float") {
      const std::uint32_t w = std::uint32_t(u);
      float v;
      std::memcpy(&v, &w, 4);
      return v;
    }
    if (type == "int") return double(std::int32_t(std::uint32_t(u)));
    if (type == "char") return double(std::int8_t(std::uint8_t(u)));
    return double(u);
  }

 private:
  void skip_space() {
    while (p_ < d_.size() && std::isspace(static_cast<unsigned char>(d_[p_]))) ++p_;
  }
  std::string d_;
  std::string where_;
  std::size_t p_ = 0;
};

bool known_type(const std::string& t) {
  return t == "double" || t == "float" || t == "int" || t == "unsigned_int" || t == "char" || t == "unsigned_char";
}

}  // namespace

void write_vtk(const Mesh& m, const std::string& path, bool binary, WorldFrame frame) {
  const std::string where = "write_vtk: " + quote(path);
  m.validate(where);
  check_ply_names(m, where);
  // UNSTRUCTURED_GRID of VTK_TRIANGLE (or VTK_VERTEX) cells: ParaView and
  // Slicer read it as they read POLYDATA, and meshio (which reads no legacy
  // POLYDATA) opens it too.
  std::string out = legacy_header("UNSTRUCTURED_GRID", binary, frame);
  LegacyOut o(out, binary);
  legacy_points(out, o, m.vertices);
  const bool tri = !m.faces.empty();
  const std::size_t ncells = tri ? m.faces.size() : m.vertices.size();
  if (ncells) {
    out += "CELLS " + std::to_string(ncells) + " " + std::to_string((tri ? 4 : 2) * ncells) + "\n";
    for (std::size_t c = 0; c < ncells; ++c) {
      if (tri) {
        o.i32(3);
        for (int v : m.faces[c]) o.i32(v);
      } else {
        o.i32(1);
        o.i32(std::int32_t(c));
      }
      o.eol();
    }
    o.end_section();
    out += "CELL_TYPES " + std::to_string(ncells) + "\n";
    for (std::size_t c = 0; c < ncells; ++c) {
      o.i32(tri ? kVtkTriangle : kVtkVertex);
      o.eol();
    }
    o.end_section();
    if (tri && !m.face_ints.empty()) {
      out += "CELL_DATA " + std::to_string(m.faces.size()) + "\n";
      for (const auto& [name, v] : m.face_ints) legacy_int_scalars(out, o, name, v);
    }
  }
  if (m.has_normals() || !m.vertex_scalars.empty()) {
    out += "POINT_DATA " + std::to_string(m.vertices.size()) + "\n";
    if (m.has_normals()) {
      out += "VECTORS Normals double\n";  // meshio reads no NORMALS section
      for (const Vec3& n : m.normals) {
        o.f64(n.x);
        o.f64(n.y);
        o.f64(n.z);
        o.eol();
      }
      o.end_section();
    }
    for (const auto& [name, v] : m.vertex_scalars) {
      out += "SCALARS " + name + " double 1\nLOOKUP_TABLE default\n";
      for (double x : v) {
        o.f64(x);
        o.eol();
      }
      o.end_section();
    }
  }
  save(out, path, where);
}

Mesh read_vtk(const std::string& path, WorldFrame* frame) {
  const std::string where = "read_vtk: " + quote(path);
  require_readable(path);
  std::string data;
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(where + ": cannot open");
    std::ostringstream s;
    s << in.rdbuf();
    data = s.str();
  }
  LegacyIn in(std::move(data), where);
  const std::string magic = in.line();
  if (magic.rfind("# vtk DataFile Version ", 0) != 0)
    in.fail("the file does not start with \"# vtk DataFile Version\"; expected a legacy VTK file");
  const double version = std::atof(magic.c_str() + 23);
  if (!(version <= 4.2 + 1e-9))
    in.fail("version " + magic.substr(23) + " (its cell arrays are OFFSETS/CONNECTIVITY); expected 4.2 or older");
  const std::string title = in.line();
  WorldFrame fr = WorldFrame::lps;
  frame_from_comment(title, fr);
  if (frame) *frame = fr;
  const std::string mode = in.word();
  if (mode != "ASCII" && mode != "BINARY") in.fail("third line " + quote(mode) + "; expected ASCII or BINARY");
  const bool binary = mode == "BINARY";
  if (in.word() != "DATASET") in.fail("expected \"DATASET POLYDATA\" or UNSTRUCTURED_GRID after " + mode);
  const std::string ds = in.word();
  const bool grid = ds == "UNSTRUCTURED_GRID";
  if (ds != "POLYDATA" && !grid)
    in.fail("DATASET " + ds + "; expected POLYDATA or UNSTRUCTURED_GRID (surface meshes and point sets)");

  Mesh m;
  // Cells in file order: POLYDATA's VERTICES then POLYGONS (kinds known), or
  // an UNSTRUCTURED_GRID's CELLS (kinds from CELL_TYPES).
  std::vector<std::vector<int>> cells;
  std::vector<int> kinds;

  bool have_points = false;
  enum class Data { none, point, cell } attr = Data::none;
  std::uint64_t attr_count = 0;
  std::map<std::string, std::vector<double>> cell_scalars;
  while (!in.at_end()) {
    const std::string key = in.word();
    if (key == "POINTS") {
      const std::uint64_t n = in.count("POINTS");
      const std::string type = in.word();
      if (type != "double" && type != "float") in.fail("POINTS type " + quote(type) + "; expected float or double");
      if (n > std::uint64_t(std::numeric_limits<int>::max()) || n * (binary ? 12 : 6) > in.remaining() + 6)
        in.fail("POINTS count " + std::to_string(n) + " is more than the file holds (truncated file or bad count?)");
      in.next_line();
      m.vertices.resize(n);
      for (auto& v : m.vertices)
        for (int c = 0; c < 3; ++c) v[c] = in.f64(binary, type, "POINTS");
      have_points = true;
    } else if (key == "VERTICES" || key == "POLYGONS" || (grid && key == "CELLS")) {
      const std::uint64_t n = in.count(key), size = in.count(key);
      if (size > in.remaining() / (binary ? 4 : 2) + 1 || n > size)
        in.fail(key + " sizes " + std::to_string(n) + " " + std::to_string(size) +
                " are more than the file holds (truncated file or bad count?)");
      in.next_line();
      std::uint64_t used = 0;
      for (std::uint64_t c = 0; c < n; ++c) {
        const double k = in.f64(binary, "int", key);
        if (!(k >= 1 && k <= double(size)) || k != std::floor(k) || used + 1 + std::uint64_t(k) > size)
          in.fail(key + " cell " + std::to_string(c) + ": bad vertex count " + std::to_string(k));
        used += 1 + std::uint64_t(k);
        std::vector<int> poly(static_cast<std::size_t>(k));
        for (int& i : poly) {
          const double x = in.f64(binary, "int", key);
          if (!(x >= 0) || x != std::floor(x) || x >= double(m.vertices.size()))
            in.fail(key + " cell " + std::to_string(c) + ": vertex index " + std::to_string(x) +
                    " is out of range; expected an integer below " + std::to_string(m.vertices.size()) +
                    " (POINTS must come first)");
          i = int(x);
        }
        if (key == "POLYGONS" && poly.size() < 3)
          in.fail("POLYGONS cell " + std::to_string(c) + " has fewer than 3 vertices");
        cells.push_back(std::move(poly));
        kinds.push_back(key == "VERTICES" ? kVtkVertex : key == "POLYGONS" ? kVtkPolygon : -1);
      }

    } else if (grid && key == "CELL_TYPES") {
      const std::uint64_t n = in.count(key);
      if (n != cells.size())
        in.fail("CELL_TYPES " + std::to_string(n) + "; expected " + std::to_string(cells.size()) + " (the CELLS count)");
      in.next_line();
      for (std::uint64_t c = 0; c < n; ++c) {
        const double t = in.f64(binary, "int", key);
        const std::size_t k = cells[c].size();
        if (!((t == kVtkVertex && k == 1) || (t == kVtkTriangle && k == 3) || (t == kVtkPolygon && k >= 3)))
          in.fail("CELL_TYPES cell " + std::to_string(c) + ": type " + std::to_string(int(t)) + " with " +
                  std::to_string(k) + " vertices; expected 1 (vertex), 5 (triangle) or 7 (polygon): surfaces and "
                  "point sets are read, tetrahedra are written, not read");
        kinds[c] = int(t);
      }
    } else if (key == "POINT_DATA" || key == "CELL_DATA") {
      attr = key == "POINT_DATA" ? Data::point : Data::cell;
      attr_count = in.count(key);
      const std::uint64_t expect = attr == Data::point ? m.vertices.size() : cells.size();
      if (attr_count != expect)
        in.fail(key + " " + std::to_string(attr_count) + "; expected " + std::to_string(expect) +
                (attr == Data::point ? " (the point count)" : " (the cell count)"));
    } else if (key == "SCALARS" || key == "NORMALS" || key == "VECTORS") {
      if (attr == Data::none) in.fail(key + " before POINT_DATA or CELL_DATA");
      const std::string name = in.word(), type = in.word();
      if (key == "VECTORS" && name != "Normals")
        in.fail("VECTORS " + name + " is not read; expected point normals (NORMALS, or VECTORS Normals)");
      if (!known_type(type)) in.fail(key + " " + name + ": unsupported type " + quote(type));
      int comps = 3;
      const std::string extra = in.rest();
      if (key == "SCALARS") {
        if (!extra.empty() && extra != "1")
          in.fail("SCALARS " + name + " has " + extra + " components; expected 1");
        comps = 1;
        if (in.word() != "LOOKUP_TABLE") in.fail("SCALARS " + name + ": expected a LOOKUP_TABLE line");
        in.rest();
      }
      std::vector<double> v(attr_count * std::uint64_t(comps));
      for (double& x : v) x = in.f64(binary, type, key + " " + name);
      if (key != "SCALARS") {
        if (attr != Data::point) in.fail("cell " + key + " are not read; expected point normals");
        m.normals.resize(attr_count);
        for (std::size_t i = 0; i < attr_count; ++i) m.normals[i] = Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
      } else if (attr == Data::point) {
        m.vertex_scalars[name] = std::move(v);
      } else {
        cell_scalars[name] = std::move(v);
      }
    } else {
      in.fail("section " + quote(key) + " is not read; expected POINTS, VERTICES, POLYGONS, POINT_DATA, "
              "CELL_DATA, SCALARS or NORMALS");
    }
  }
  if (!have_points) in.fail("no POINTS section");
  for (std::size_t c = 0; c < cells.size(); ++c) {
    if (kinds[c] < 0) in.fail("CELLS without CELL_TYPES");
    if (kinds[c] == kVtkVertex) continue;
    const auto& p = cells[c];
    for (std::size_t k = 1; k + 1 < p.size(); ++k) {
      m.faces.push_back({p[0], p[k], p[k + 1]});
      for (const auto& [name, v] : cell_scalars) {
        const double x = std::round(v[c]);
        if (!(std::fabs(x) <= double(std::numeric_limits<int>::max())))
          in.fail("CELL_DATA " + name + ": value " + std::to_string(x) + " does not fit an int");
        m.face_ints[name].push_back(int(x));
      }
    }
  }
  return m;
}

void write_vtp(const Mesh& m, const std::string& path, WorldFrame frame) {
  const std::string where = "write_vtp: " + quote(path);
  m.validate(where);
  check_ply_names(m, where);
  const bool points_only = m.faces.empty();
  std::string out = xml_head("PolyData", frame, true);
  out += "    <Piece NumberOfPoints=\"" + std::to_string(m.vertices.size()) + "\" NumberOfVerts=\"" +
         std::to_string(points_only ? m.vertices.size() : 0) +
         "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"" + std::to_string(m.faces.size()) + "\">\n";
  xml_point_data(out, m);
  if (!m.face_ints.empty()) {
    out += "      <CellData>\n";
    for (const auto& [name, v] : m.face_ints) xml_ints(out, "Int32", name, v);
    out += "      </CellData>\n";
  }
  out += "      <Points>\n";
  xml_vec3s(out, "Points", m.vertices);
  out += "      </Points>\n";
  std::vector<std::int64_t> conn, offsets;
  if (points_only) {
    for (std::size_t i = 0; i < m.vertices.size(); ++i) {
      conn.push_back(std::int64_t(i));
      offsets.push_back(std::int64_t(i + 1));
    }
  } else {
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
      for (int v : m.faces[f]) conn.push_back(v);
      offsets.push_back(std::int64_t(3 * (f + 1)));
    }
  }
  out += points_only ? "      <Verts>\n" : "      <Polys>\n";
  xml_ints(out, "Int64", "connectivity", conn);
  xml_ints(out, "Int64", "offsets", offsets);
  out += points_only ? "      </Verts>\n" : "      </Polys>\n";
  out += "    </Piece>\n  </PolyData>\n</VTKFile>\n";
  save(out, path, where);
}

void write_vtk_tets(const LabelledTets& t, const std::string& path, bool binary, WorldFrame frame) {
  const std::string where = "write_vtk: " + quote(path);
  t.validate(where);
  std::string out = legacy_header("UNSTRUCTURED_GRID", binary, frame);
  LegacyOut o(out, binary);
  legacy_points(out, o, t.vertices);
  out += "CELLS " + std::to_string(t.tets.size()) + " " + std::to_string(5 * t.tets.size()) + "\n";
  for (const auto& c : t.tets) {
    o.i32(4);
    for (int v : c) o.i32(v);
    o.eol();
  }
  o.end_section();
  out += "CELL_TYPES " + std::to_string(t.tets.size()) + "\n";
  for (std::size_t i = 0; i < t.tets.size(); ++i) {
    o.i32(kVtkTetra);
    o.eol();
  }
  o.end_section();
  out += "CELL_DATA " + std::to_string(t.tets.size()) + "\n";
  legacy_int_scalars(out, o, "material", t.materials);
  save(out, path, where);
}

void write_vtu(const LabelledTets& t, const std::string& path, WorldFrame frame) {
  const std::string where = "write_vtu: " + quote(path);
  t.validate(where);
  std::string out = xml_head("UnstructuredGrid", frame, false);
  out += "    <Piece NumberOfPoints=\"" + std::to_string(t.vertices.size()) + "\" NumberOfCells=\"" +
         std::to_string(t.tets.size()) + "\">\n";
  out += "      <CellData Scalars=\"material\">\n";
  xml_ints(out, "Int32", "material", t.materials);
  out += "      </CellData>\n      <Points>\n";
  xml_vec3s(out, "Points", t.vertices);
  out += "      </Points>\n      <Cells>\n";
  std::vector<std::int64_t> conn, offsets;
  std::vector<int> types(t.tets.size(), kVtkTetra);
  for (std::size_t c = 0; c < t.tets.size(); ++c) {
    for (int v : t.tets[c]) conn.push_back(v);
    offsets.push_back(std::int64_t(4 * (c + 1)));
  }
  xml_ints(out, "Int64", "connectivity", conn);
  xml_ints(out, "Int64", "offsets", offsets);
  xml_ints(out, "UInt8", "types", types);
  out += "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  save(out, path, where);
}

// ---- legacy UNSTRUCTURED_GRID as tetrahedra ----

namespace {

// Bytes of a legacy data type in BINARY files (0: not a type we read).
int legacy_type_size(const std::string& t) {
  if (t == "unsigned_char" || t == "char" || t == "vtktypeint8" || t == "vtktypeuint8") return 1;
  if (t == "short" || t == "unsigned_short" || t == "vtktypeint16" || t == "vtktypeuint16") return 2;
  if (t == "int" || t == "unsigned_int" || t == "float" || t == "vtktypeint32" || t == "vtktypeuint32" ||
      t == "vtktypefloat32")
    return 4;
  if (t == "long" || t == "unsigned_long" || t == "double" || t == "vtktypeint64" || t == "vtktypeuint64" ||
      t == "vtktypefloat64" || t == "vtkIdType")
    return 8;
  return 0;
}

class LegacyTetReader {
 public:
  LegacyTetReader(const std::string& data, const std::string& where) : in_(data, where), where_(where) {}

  LabelledTets read(WorldFrame& frame) {
    const std::string magic = in_.line();
    if (magic.rfind("# vtk DataFile Version ", 0) != 0)
      in_.fail("the file does not start with \"# vtk DataFile Version\"; expected a legacy VTK file");
    version_ = std::atof(magic.c_str() + 23);
    const std::string title = in_.line();
    frame_from_comment(title, frame);
    const std::string mode = in_.word();
    if (mode != "ASCII" && mode != "BINARY") in_.fail("third line " + quote(mode) + "; expected ASCII or BINARY");
    binary_ = mode == "BINARY";
    if (in_.word() != "DATASET") in_.fail("expected \"DATASET UNSTRUCTURED_GRID\" after " + mode);
    const std::string ds = in_.word();
    if (ds != "UNSTRUCTURED_GRID")
      in_.fail("DATASET " + quote(ds.substr(0, 40)) + "; expected UNSTRUCTURED_GRID (a tetrahedral mesh)");
    bool have_points = false, have_types = false;
    while (!in_.at_end()) {
      const std::string key = in_.word();
      if (key == "POINTS") {
        const std::uint64_t n = count("POINTS", 3);
        const std::string type = in_.word();
        data_type(type, "POINTS");
        in_.next_line();
        points_.resize(n);
        for (auto& p : points_)
          for (int c = 0; c < 3; ++c) {
            p[c] = value(type, "POINTS");
            if (!std::isfinite(p[c])) in_.fail("POINTS: a coordinate is " + format_number(p[c]) + "; expected finite");
          }
        have_points = true;
      } else if (key == "CELLS") {
        version_ >= 5 ? cells5() : cells4();
      } else if (key == "CELL_TYPES") {
        const std::uint64_t n = count("CELL_TYPES", 1);
        if (n + 1 != cells_.begin.size())
          in_.fail("CELL_TYPES " + std::to_string(n) + "; expected " +
                   std::to_string(cells_.begin.empty() ? 0 : cells_.begin.size() - 1) + " (the CELLS count; CELLS first)");
        in_.next_line();
        cells_.types.resize(n);
        for (int& t : cells_.types) t = int(integer("int", "CELL_TYPES"));
        have_types = true;
      } else if (key == "CELL_DATA" || key == "POINT_DATA") {
        cell_data_ = key == "CELL_DATA";
        attr_count_ = count(key, 1);
        const std::size_t expect = cell_data_ ? cells_.types.size() : points_.size();
        if (attr_count_ != expect)
          in_.fail(key + " " + std::to_string(attr_count_) + "; expected " + std::to_string(expect) +
                   (cell_data_ ? " (the cell count)" : " (the point count)"));
        in_.next_line();
      } else if (key == "SCALARS") {
        need_attributes(key);
        const std::string name = in_.word(), type = in_.word();
        data_type(type, "SCALARS " + name);
        const std::string extra = in_.line();
        const int comps = extra.empty() ? 1 : std::atoi(extra.c_str());
        if (comps < 1 || comps > 4) in_.fail("SCALARS " + name + ": " + quote(extra) + " components; expected 1 to 4");
        if (in_.word() != "LOOKUP_TABLE") in_.fail("SCALARS " + name + ": expected a LOOKUP_TABLE line");
        in_.line();
        array(name, type, std::uint64_t(comps));
      } else if (key == "FIELD") {
        // In CELL_DATA / POINT_DATA: arrays of one value per cell or point;
        // before them (dataset level, e.g. TIME): arrays of any length, skipped.
        const bool dataset_level = attr_count_ == std::uint64_t(-1);
        in_.word();
        const std::uint64_t arrays = count("FIELD array count", 1);
        in_.next_line();
        for (std::uint64_t a = 0; a < arrays; ++a) {
          const std::string name = in_.word();
          if (name == "NULL_ARRAY") continue;
          const std::uint64_t comps = count("FIELD " + name + " components", 1);
          const std::uint64_t tuples = count("FIELD " + name + " tuples", 1);
          const std::string type = in_.word();
          data_type(type, "FIELD " + name);
          if (!dataset_level && tuples != attr_count_)
            in_.fail("FIELD " + name + ": " + std::to_string(tuples) + " tuples; expected " + std::to_string(attr_count_));
          in_.next_line();
          array(dataset_level ? "" : name, type, comps, dataset_level ? tuples : attr_count_);
        }
      } else if (key == "VECTORS" || key == "NORMALS" || key == "TENSORS" || key == "TENSORS6" ||
                 key == "GLOBAL_IDS" || key == "PEDIGREE_IDS") {
        need_attributes(key);
        const std::string name = in_.word(), type = in_.word();
        data_type(type, key + " " + name);
        in_.next_line();
        const std::uint64_t comps = key == "TENSORS" ? 9 : key == "TENSORS6" ? 6 : key[0] == 'G' || key[0] == 'P' ? 1 : 3;
        array("", type, comps);
      } else if (key == "TEXTURE_COORDINATES") {
        need_attributes(key);
        const std::string name = in_.word();
        const std::uint64_t dim = count(key + " dimension", 1);
        const std::string type = in_.word();
        data_type(type, key + " " + name);
        in_.next_line();
        array("", type, dim);
      } else if (key == "COLOR_SCALARS") {
        need_attributes(key);
        in_.word();
        const std::uint64_t comps = count(key + " components", 1);
        in_.next_line();
        array("", binary_ ? "unsigned_char" : "float", comps);
      } else if (key == "LOOKUP_TABLE") {
        in_.word();
        const std::uint64_t size = count(key + " size", 4);
        in_.next_line();
        for (std::uint64_t i = 0; i < 4 * size; ++i) value(binary_ ? "unsigned_char" : "float", key);
      } else if (key == "METADATA") {
        // VTK 9's array information: lines up to an empty one.
        in_.next_line();
        while (in_.remaining() > 0 && !in_.line().empty()) {
        }
      } else {
        in_.fail("section " + quote(key.substr(0, 40)) +
                 " is not read; expected POINTS, CELLS, CELL_TYPES, CELL_DATA, POINT_DATA, SCALARS or FIELD");
      }
    }
    if (!have_points) in_.fail("no POINTS section");
    if (!cells_.begin.empty() && !have_types) in_.fail("CELLS without CELL_TYPES");
    if (cells_.begin.empty()) cells_.begin.push_back(0);
    return vtk_cells::to_tets(std::move(points_), cells_, arrays_, where_);
  }

 private:
  std::uint64_t count(const std::string& what, std::uint64_t min_bytes) {
    const long long n = in_.integer(what + " count", 0, std::numeric_limits<int>::max());
    if (std::uint64_t(n) > in_.remaining() / std::max<std::uint64_t>(1, min_bytes) + 1)
      in_.fail(what + " count " + std::to_string(n) + " is more than the file holds (truncated or a bad count?)");
    return std::uint64_t(n);
  }
  void data_type(const std::string& t, const std::string& what) {
    if (legacy_type_size(t) == 0) in_.fail(what + ": data type " + quote(t.substr(0, 40)) + " is not read");
  }
  void need_attributes(const std::string& key) {
    if (attr_count_ == std::uint64_t(-1)) in_.fail(key + " before CELL_DATA or POINT_DATA");
  }
  double value(const std::string& type, const std::string& what) {
    if (!binary_) return in_.number(what);
    const int n = legacy_type_size(type);
    if (type == "float" || type == "vtktypefloat32") return in_.f32(true, what);
    if (type == "double" || type == "vtktypefloat64") return in_.f64(true, what);
    const bool is_unsigned = type.find("unsigned") != std::string::npos || type.find("uint") != std::string::npos;
    return is_unsigned ? double(in_.uint(n, true, what)) : double(in_.sint(n, true, what));
  }
  // An integer value (cell sizes, indices, types).
  long long integer(const std::string& type, const std::string& what) {
    const double v = value(type, what);
    if (!(std::fabs(v) < 9.0e15) || v != std::floor(v)) in_.fail(what + ": " + format_number(v) + " is not an integer");
    return (long long)v;
  }
  // Attribute data: kept (the first component) under `name` for one-component cell arrays.
  void array(const std::string& name, const std::string& type, std::uint64_t comps) {
    array(name, type, comps, attr_count_);
  }
  void array(const std::string& name, const std::string& type, std::uint64_t comps, std::uint64_t tuples) {
    if (comps == 0 || comps > 64) in_.fail(name + ": " + std::to_string(comps) + " components; expected 1 to 64");
    if (tuples * comps > in_.remaining() + 1)
      in_.fail(name + ": " + std::to_string(tuples * comps) + " values are more than the file holds (truncated?)");
    std::vector<double> v;
    const bool keep = cell_data_ && comps == 1 && !name.empty();
    if (keep) v.reserve(tuples);
    for (std::uint64_t i = 0; i < tuples * comps; ++i) {
      const double x = value(type, name.empty() ? "attribute data" : name);
      if (keep) v.push_back(x);
    }
    if (keep) arrays_[name] = std::move(v);
  }
  void cells4() {
    const std::uint64_t n = count("CELLS", 2), size = count("CELLS size", 1);
    if (n > size) in_.fail("CELLS " + std::to_string(n) + " " + std::to_string(size) + ": more cells than values");
    in_.next_line();
    cells_.begin.assign(1, 0);
    cells_.conn.reserve(size - n);
    std::uint64_t used = 0;
    for (std::uint64_t c = 0; c < n; ++c) {
      const long long k = integer("int", "CELLS cell " + std::to_string(c) + " size");
      if (k < 0 || used + 1 + std::uint64_t(k) > size)
        in_.fail("CELLS cell " + std::to_string(c) + ": " + std::to_string(k) + " vertices; more than the " +
                 std::to_string(size) + " values the header announces");
      used += 1 + std::uint64_t(k);
      for (long long j = 0; j < k; ++j) cells_.conn.push_back(double(integer("int", "CELLS cell " + std::to_string(c))));
      cells_.begin.push_back(cells_.conn.size());
    }
    if (used != size) in_.fail("CELLS: " + std::to_string(used) + " values in the cells; expected " + std::to_string(size));
  }
  void cells5() {
    const std::uint64_t noff = count("CELLS offsets", 1), nconn = count("CELLS connectivity", 1);
    if (noff == 0) in_.fail("CELLS 0 " + std::to_string(nconn) + "; expected at least one offset");
    in_.next_line();
    if (in_.word() != "OFFSETS") in_.fail("CELLS: expected OFFSETS (version 5 files)");
    std::string type = in_.word();
    data_type(type, "OFFSETS");
    in_.next_line();
    cells_.begin.resize(noff);
    for (std::uint64_t i = 0; i < noff; ++i) {
      const long long o = integer(type, "OFFSETS");
      if (o < 0 || std::uint64_t(o) > nconn || (i > 0 && std::size_t(o) < cells_.begin[i - 1]) || (i == 0 && o != 0))
        in_.fail("OFFSETS " + std::to_string(i) + ": " + std::to_string(o) +
                 "; expected non-decreasing offsets from 0 up to the connectivity size " + std::to_string(nconn));
      cells_.begin[i] = std::size_t(o);
    }
    if (cells_.begin.back() != nconn)
      in_.fail("OFFSETS: the last offset " + std::to_string(cells_.begin.back()) + "; expected " + std::to_string(nconn));
    if (in_.word() != "CONNECTIVITY") in_.fail("CELLS: expected CONNECTIVITY after the offsets");
    type = in_.word();
    data_type(type, "CONNECTIVITY");
    in_.next_line();
    cells_.conn.resize(nconn);
    for (double& v : cells_.conn) v = double(integer(type, "CONNECTIVITY"));
  }

  scan::Cursor in_;
  std::string where_;
  double version_ = 4.2;
  bool binary_ = false, cell_data_ = false;
  std::uint64_t attr_count_ = std::uint64_t(-1);
  std::vector<Vec3> points_;
  vtk_cells::Cells cells_;
  std::map<std::string, std::vector<double>> arrays_;
};

}  // namespace

LabelledTets read_vtk_tets(const std::string& path, WorldFrame* frame) {
  const std::string where = "read_vtk: " + quote(path);
  const std::string data = scan::slurp(path, where);
  WorldFrame fr = WorldFrame::lps;
  LabelledTets t = LegacyTetReader(data, where).read(fr);
  if (frame) *frame = fr;
  return t;
}

}  // namespace pm
