// OFF, OBJ and STL through CGAL's polygon-soup IO. The only translation unit
// that includes CGAL's IO headers (they compile slowly).
#include <CGAL/IO/OBJ.h>
#include <CGAL/IO/OFF.h>
#include <CGAL/IO/STL.h>
#include <CGAL/Simple_cartesian.h>

#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>

#include "pm/base/error.h"
#include "pm/io/mesh_formats.h"

namespace pm {
namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Polygons = std::vector<std::vector<std::size_t>>;

std::vector<Vec3> to_vec3(const std::vector<Point>& pts) {
  std::vector<Vec3> v;
  v.reserve(pts.size());
  for (const Point& p : pts) v.emplace_back(p.x(), p.y(), p.z());
  return v;
}

void to_soup(const Mesh& m, std::vector<Point>& pts, Polygons& polys) {
  pts.reserve(m.vertices.size());
  for (const Vec3& v : m.vertices) pts.emplace_back(v.x, v.y, v.z);
  polys.reserve(m.faces.size());
  for (const auto& f : m.faces) polys.push_back({std::size_t(f[0]), std::size_t(f[1]), std::size_t(f[2])});
}

std::uintmax_t file_size(const std::string& path, const std::string& fn) {
  std::error_code ec;
  const std::uintmax_t n = std::filesystem::file_size(path, ec);
  if (ec) throw IoError(fn + ": " + quote(path) + ": cannot determine the file size: " + ec.message());
  return n;
}

// CGAL's OFF reader resizes its arrays to the header's counts before reading
// any data: check them against the file size first. Handles the common header
// forms ([ST][C][N][4][n]OFF [BINARY], comments); anything else is left to CGAL.
void check_off_counts(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string text(4096, '\0');
  in.read(&text[0], std::streamsize(text.size()));
  text.resize(std::size_t(in.gcount()));
  std::istringstream is(text);
  std::vector<std::string> words;
  std::string line;
  while (words.size() < 6 && std::getline(is, line)) {
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    std::istringstream ls(line);
    std::string w;
    while (ls >> w) words.push_back(w);
  }
  if (words.empty()) return;
  const std::string& key = words[0];
  if (key.size() < 3 || key.compare(key.size() - 3, 3, "OFF") != 0) return;
  std::size_t i = 1;
  const bool binary = i < words.size() && words[i] == "BINARY";
  if (binary) ++i;
  if (key.find('n') != std::string::npos) ++i;  // nOFF: dimension first
  if (i + 1 >= words.size()) return;
  std::uint64_t nv = 0, nf = 0;
  try {
    const long long v = std::stoll(words[i]), f = std::stoll(words[i + 1]);
    if (v < 0 || f < 0) return;  // CGAL reports these
    nv = std::uint64_t(v);
    nf = std::uint64_t(f);
  } catch (const std::exception&) {
    return;
  }
  // Smallest records: ASCII "0 0 0\n" and "0\n"; binary 3 floats and one int.
  const std::uint64_t vb = binary ? 12 : 6, fb = binary ? 4 : 2;
  const std::uint64_t size = file_size(path, "read_off");
  if (nv > size / vb || nf > size / fb || nv * vb + nf * fb > size)
    throw InputError("read_off: " + quote(path) + ": the header declares " + std::to_string(nv) + " vertices and " +
                     std::to_string(nf) + " faces, more than a file of " + std::to_string(size) +
                     " bytes can hold (truncated file or bad counts?)");
}

// CGAL's ASCII facet scanner converts each facet's vertex count from double
// to std::size_t unchecked, undefined for a count <= -1, NaN or beyond 2^64
// (found by fuzz_off; tests/data/regress/off-negative-facet-size*). Walk a
// plain ASCII "OFF" file the way CGAL's scanner does (the counts as tokens,
// then one record per line after skipping white space and # comments, the
// first vertex record starting right after the counts) and check the first
// number of every facet record first. Other variants (COFF, NOFF, BINARY, ...)
// are left to CGAL.
void check_off_facet_counts(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::size_t pos = 0;
  const auto skip_space_and_comments = [&] {
    for (;;) {
      while (pos < text.size() && std::isspace(static_cast<unsigned char>(text[pos]))) ++pos;
      if (pos < text.size() && text[pos] == '#') {
        while (pos < text.size() && text[pos] != '\n') ++pos;
        continue;
      }
      return;
    }
  };
  std::string head[4];
  for (int i = 0; i < 4; ++i) {
    skip_space_and_comments();
    const std::size_t b = pos;
    if (i == 0) {
      // The keyword as CGAL reads it: its first character, then letters and
      // digits; the character that ends it is consumed ("OFF\x0f4 4 0" is
      // keyword OFF with 4 vertices; fuzz_off, tests/data/regress/off-keyword-index).
      if (pos < text.size()) ++pos;
      while (pos < text.size() && std::isalnum(static_cast<unsigned char>(text[pos]))) ++pos;
      head[0] = text.substr(b, pos - b);
      if (pos < text.size()) ++pos;
      continue;
    }
    const bool word = i == 1 && pos < text.size() && !std::isdigit(static_cast<unsigned char>(text[pos]));
    if (word) {
      // CGAL reads a word after the keyword the same way: its first
      // character, then letters and digits ("BINARY\0..." is BINARY; fuzz_off,
      // tests/data/regress/off-binary-nul).
      ++pos;
      while (pos < text.size() && std::isalnum(static_cast<unsigned char>(text[pos]))) ++pos;
    } else {
      while (pos < text.size() && !std::isspace(static_cast<unsigned char>(text[pos])) && text[pos] != '#') ++pos;
    }
    head[i] = text.substr(b, pos - b);
    const std::string& key = head[0];
    const bool off_family = key.size() >= 3 && key.compare(key.size() - 3, 3, "OFF") == 0;
    if (word && off_family && head[1] == "BINARY") {
      // Binary counts: three big-endian int32 after the BINARY line. CGAL
      // casts an estimate from them to int unchecked (fuzz_off,
      // tests/data/regress/off-binary-huge-counts): check them against the size.
      while (pos < text.size() && text[pos] != '\n') ++pos;
      ++pos;
      if (pos + 12 > text.size()) return;  // truncated: CGAL reports it
      std::int64_t c[3];
      for (int k = 0; k < 3; ++k) {
        const auto* u = reinterpret_cast<const unsigned char*>(text.data() + pos + 4 * k);
        c[k] = std::int32_t(std::uint32_t(u[0]) << 24 | std::uint32_t(u[1]) << 16 | std::uint32_t(u[2]) << 8 | u[3]);
      }
      const std::int64_t size = std::int64_t(text.size());
      if (c[0] < 0 || c[1] < 0 || c[2] < 0 || c[0] > size / 12 || c[1] > size / 4 || c[2] > size)
        throw InputError("read_off: " + quote(path) + ": the binary header declares " + std::to_string(c[0]) +
                         " vertices, " + std::to_string(c[1]) + " faces and " + std::to_string(c[2]) +
                         " edges, impossible in a file of " + std::to_string(size) + " bytes");
      return;
    }
  }
  // OFF and its variants with per-line records and no dimension line (COFF,
  // NOFF, STOFF, 4OFF, ...); nOFF is left to CGAL.
  const std::string& kw = head[0];
  if (kw.size() < 3 || kw.compare(kw.size() - 3, 3, "OFF") != 0 || kw.find('n') != std::string::npos) return;
  long long nv = 0, nf = 0;
  try {
    nv = std::stoll(head[1]);
    nf = std::stoll(head[2]);
  } catch (const std::exception&) {
    return;
  }
  if (nv < 0 || nf < 0) return;
  // CGAL reserves its vectors by these counts (fuzz_off: 66,666,664 faces
  // after "OFF\x0f" in a 41-byte file, tests/data/regress/off-keyword-counts).
  if (nv > std::int64_t(text.size()) || nf > std::int64_t(text.size()))
    throw InputError("read_off: " + quote(path) + ": the header declares " + std::to_string(nv) + " vertices and " +
                     std::to_string(nf) + " faces, more than a file of " + std::to_string(text.size()) +
                     " bytes can hold (truncated file or bad counts?)");
  const auto next_record = [&](std::string& out) {
    skip_space_and_comments();
    if (pos >= text.size()) return false;
    std::size_t e = text.find('\n', pos);
    if (e == std::string::npos) e = text.size();
    out = text.substr(pos, e - pos);
    pos = e;
    const auto hash = out.find('#');
    if (hash != std::string::npos) out.erase(hash);
    return true;
  };
  std::string rec;
  for (long long k = 0; k < nv; ++k)
    if (!next_record(rec)) return;  // truncated: CGAL reports it
  for (long long f = 0; f < nf; ++f) {
    if (!next_record(rec)) return;
    // CGAL splits the record by reading doubles from it ("1-2" is 1 and -2),
    // converts the first to the vertex count and resizes the facet with it,
    // then converts each index, all from double to std::size_t unchecked:
    // undefined for values <= -1, NaN or beyond 2^64, and a count beyond the
    // file's size exhausts memory (fuzz_off, tests/data/regress/off-*).
    const auto num = [](double v) {
      std::ostringstream o;
      o << v;
      return o.str();
    };
    std::istringstream ls(rec);
    double c = 0;
    if (!(ls >> c)) continue;  // CGAL reports the malformed record
    const double limit = double(text.size());
    if (!(c > -1 && c <= limit))
      throw InputError("read_off: " + quote(path) + ": facet " + std::to_string(f) + " has vertex count " +
                       num(c) + "; expected an integer >= 3, at most the file's size");
    double idx = 0;
    for (long long k = 0; k < static_cast<long long>(c) && ls >> idx; ++k)
      if (!(idx > -1 && idx < 1e18))
        throw InputError("read_off: " + quote(path) + ": facet " + std::to_string(f) + " has vertex index " +
                         num(idx) + "; expected an integer in [0, " + std::to_string(nv) + ")");
  }
}

}  // namespace

Mesh read_off(const std::string& path) {
  check_off_counts(path);
  check_off_facet_counts(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("read_off: " + quote(path) + ": cannot open");
  std::vector<Point> pts;
  Polygons polys;
  if (!CGAL::IO::read_OFF(in, pts, polys, CGAL::parameters::verbose(false)))
    throw InputError("read_off: " + quote(path) +
                     ": malformed OFF (bad header, truncated data, bad number or vertex index out of range); "
                     "expected \"OFF\", the counts \"V F E\", V vertices and F faces");
  return mesh_from_polygons(to_vec3(pts), polys, "read_off", path);
}

void write_off(const Mesh& m, const std::string& path) {
  std::vector<Point> pts;
  Polygons polys;
  to_soup(m, pts, polys);
  std::ofstream os(path);
  if (!os || !CGAL::IO::write_OFF(os, pts, polys, CGAL::parameters::stream_precision(17)))
    throw IoError("write_off: " + quote(path) + ": write failed");
  os.close();
  if (!os) throw IoError("write_off: " + quote(path) + ": write failed (disk full?)");
}

Mesh read_obj(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError("read_obj: " + quote(path) + ": cannot open");
  std::vector<Point> pts;
  Polygons polys;
  if (!CGAL::IO::read_OBJ(in, pts, polys, CGAL::parameters::verbose(false)))
    throw InputError("read_obj: " + quote(path) +
                     ": malformed OBJ (unknown record, bad number, face index out of range, or no vertices or "
                     "faces); expected \"v x y z\" and \"f i j k ...\" records");
  return mesh_from_polygons(to_vec3(pts), polys, "read_obj", path);
}

void write_obj(const Mesh& m, const std::string& path) {
  std::vector<Point> pts;
  Polygons polys;
  to_soup(m, pts, polys);
  std::ofstream os(path);
  if (!os || !CGAL::IO::write_OBJ(os, pts, polys, CGAL::parameters::stream_precision(17)))
    throw IoError("write_obj: " + quote(path) + ": write failed");
  os.close();
  if (!os) throw IoError("write_obj: " + quote(path) + ": write failed (disk full?)");
}

Mesh read_stl(const std::string& path) {
  {
    std::ifstream probe(path);
    if (!probe) throw IoError("read_stl: " + quote(path) + ": cannot open");
  }
  std::vector<Point> pts;
  Polygons polys;
  if (!CGAL::IO::read_STL(path, pts, polys, CGAL::parameters::verbose(false)))
    throw InputError("read_stl: " + quote(path) +
                     ": malformed STL (truncated binary data or bad ASCII facet); expected binary STL or "
                     "\"solid ... facet normal ... outer loop vertex x y z ...\"");
  if (polys.empty())
    throw InputError("read_stl: " + quote(path) + ": no triangles; expected at least one facet");
  return mesh_from_polygons(to_vec3(pts), polys, "read_stl", path);
}

void write_stl(const Mesh& m, const std::string& path, bool binary) {
  if (m.faces.empty())
    throw InputError("write_stl: " + quote(path) + ": the mesh has no faces; STL stores triangles only");
  std::vector<Point> pts;
  Polygons polys;
  to_soup(m, pts, polys);
  if (!CGAL::IO::write_STL(path, pts, polys,
                           CGAL::parameters::use_binary_mode(binary).stream_precision(17)))
    throw IoError("write_stl: " + quote(path) + ": write failed");
}

}  // namespace pm
