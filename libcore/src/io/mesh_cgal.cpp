// OFF, OBJ and STL through CGAL's polygon-soup IO. The only translation unit
// that includes CGAL's IO headers (they compile slowly).
#include <CGAL/IO/OBJ.h>
#include <CGAL/IO/OFF.h>
#include <CGAL/IO/STL.h>
#include <CGAL/Simple_cartesian.h>

#include <cctype>
#include <cmath>
#include <cstring>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>

#include "pm/base/error.h"
#include "pm/io/mesh_cgal.h"
#include "pm/io/polygon_soup.h"

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

// CGAL 5.5's OFF reader (File_header_OFF, File_scanner_OFF, IO/OFF.h) trusts
// the file in several places, each found by fuzz_off and kept in
// tests/data/regress/off-*:
//  * it resizes its arrays to the header's counts before reading any data, and
//    converts an edge-count estimate from them to int unchecked;
//  * it converts each facet's vertex count and indices from double to
//    std::size_t unchecked, and resizes the facet to that count;
//  * with colours (C...OFF) it computes the number of colour values of a record
//    as an unsigned difference and then indexes the record's numbers with it
//    (an empty record, two values, or a record without colour after one with
//    colour read past the end), converts a colour index to int and indexes a
//    149-entry colour map with it, and converts colour values to unsigned char,
//    all unchecked;
//  * with texture coordinates but no colours (STOFF) it indexes the record
//    from an offset it never set.
// OffCheck walks the file as CGAL's scanner does (the same keyword, word,
// number and record rules) and refuses any of these with a message naming the
// record, before CGAL reads it. What CGAL itself reports cleanly is left to it.
class OffCheck {
 public:
  explicit OffCheck(const std::string& path) : path_(path) {
    std::ifstream in(path, std::ios::binary);
    text_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }

  void run() {
    skip_space_and_comments();
    const std::string kw = word();
    // [ST][C][N][4][n]OFF, in this order, as CGAL parses the keyword.
    std::size_t j = 0;
    const auto flag = [&](const char* f) {
      const std::size_t n = std::strlen(f);
      if (kw.compare(j, n, f) != 0) return false;
      j += n;
      return true;
    };
    st_ = flag("ST");
    c_ = flag("C");
    n_ = flag("N");
    h_ = flag("4");
    const bool dim = flag("n");
    if (kw.compare(j, std::string::npos, "OFF") != 0) return;  // not OFF (or SKEL): CGAL reports it
    skip_space_and_comments();
    if (pos_ < text_.size() && !std::isdigit(static_cast<unsigned char>(text_[pos_]))) {
      if (word() != "BINARY") return;  // CGAL reports it
      if (pos_ > 0 && text_[pos_ - 1] != '\n') {
        while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
        ++pos_;
      }
      binary(dim);
      return;
    }
    ascii(dim);
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError("read_off: " + quote(path_) + ": " + what);
  }
  static std::string num(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
  }
  std::size_t size() const { return text_.size(); }

  void skip_space_and_comments() {
    for (;;) {
      while (pos_ < size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
      if (pos_ >= size() || text_[pos_] != '#') return;
      while (pos_ < size() && text_[pos_] != '\n') ++pos_;
    }
  }
  // A word as CGAL reads one: its first character, then letters and digits;
  // the character that ends it is consumed ("OFF\x0f4 4 0" is OFF and 4).
  std::string word() {
    const std::size_t b = pos_;
    if (pos_ < size()) ++pos_;
    while (pos_ < size() && std::isalnum(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    const std::string w = text_.substr(b, pos_ - b);
    if (pos_ < size()) ++pos_;
    return w;
  }
  // `in >> int`: white space, a sign, digits (any number of them: leading
  // zeros count for nothing; fuzz_off, tests/data/regress/off-count-leading-zeros).
  // False without digits; values beyond int (where CGAL's read fails) are
  // kept, saturated at 10^18, for the caller to refuse by name.
  bool integer(long long& v) {
    while (pos_ < size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    std::size_t e = pos_;
    const bool negative = e < size() && text_[e] == '-';
    if (e < size() && (text_[e] == '+' || text_[e] == '-')) ++e;
    const std::size_t digits = e;
    constexpr long long kMax = 1000000000000000000LL;
    long long x = 0;
    for (; e < size() && std::isdigit(static_cast<unsigned char>(text_[e])); ++e)
      x = x > kMax / 10 ? kMax : x * 10 + (text_[e] - '0');
    if (e == digits) return false;
    pos_ = e;
    v = negative ? -x : x;
    return true;
  }
  // The numbers of the next record, as CGAL's scanner reads them: white space
  // and # comment lines skipped, one line, cut at '#', then doubles read with
  // `>>` until one fails (CGAL's IO::iformat is plain `>>` outside MSVC, so
  // "1-2" is 1 and -2, and "2e" fails). False at the end of the file.
  bool record(std::vector<double>& out) {
    out.clear();
    skip_space_and_comments();
    if (pos_ >= size()) return false;
    std::size_t e = text_.find('\n', pos_);
    if (e == std::string::npos) e = size();
    std::size_t end = text_.find('#', pos_);
    if (end > e) end = e;
    std::istringstream line(text_.substr(pos_, end - pos_));
    pos_ = e;
    double d = 0;
    while (line >> d) out.push_back(d);
    return true;
  }

  // Colour values c0.. of a record, as CGAL's scan_color converts them.
  void check_colour(const std::vector<double>& v, std::size_t first, std::size_t count, const std::string& what) const {
    if (count == 1) {
      if (!(v[first] > -1 && v[first] < 2147483648.0))
        fail(what + " has colour-map index " + num(v[first]) + "; expected an integer >= 0");
      return;
    }
    const bool integral = std::floor(v[first]) == v[first] && std::floor(v[first + 1]) == v[first + 1] &&
                          std::floor(v[first + 2]) == v[first + 2];
    for (std::size_t k = first; k < first + 3; ++k) {
      const double byte = integral ? v[k] : v[k] * 255;
      if (!(byte > -1 && byte < 256))
        fail(what + " has colour value " + num(v[k]) + "; expected an integer in [0, 255] or a number in [0, 1]");
    }
  }
  // A record's colour count: 0, 1, 3 or 4, and never 0 again once a record
  // had colour (CGAL then reads a colour from every record).
  void colour_count(long long count, bool& seen, const std::string& what) const {
    if (count < 0 || count == 2 || count > 4 || (seen && count == 0))
      fail(what + " has " + std::to_string(count < 0 ? 0 : count) +
           " colour values; expected 0, 1, 3 or 4" + (seen ? " (and not 0: earlier records have colour)" : ""));
    seen = seen || count > 0;
  }

  void counts_fit(long long nv, long long nf, std::uint64_t vb, std::uint64_t fb) const {
    // Smallest records: ASCII "0 0 0\n" and "0\n"; binary 3 floats and one int.
    if (std::uint64_t(nv) > size() / vb || std::uint64_t(nf) > size() / fb ||
        std::uint64_t(nv) * vb + std::uint64_t(nf) * fb > size())
      fail("the header declares " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
           " faces, more than a file of " + std::to_string(size()) + " bytes can hold (truncated file or bad counts?)");
  }

  void ascii(bool dim) {
    long long d = 0, nv = 0, nf = 0, ne = 0;
    if (dim && !integer(d)) return;
    if (!integer(nv) || !integer(nf) || !integer(ne)) return;  // CGAL reports these
    // CGAL refuses a negative face count but takes a negative vertex count as
    // a huge size; counts beyond int it cannot read.
    if (nv < 0 || nf < 0)
      fail("the header declares " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
           " faces; expected counts >= 0");
    counts_fit(nv, nf, 6, 2);
    if (nv > std::numeric_limits<int>::max() || nf > std::numeric_limits<int>::max())
      fail("the header's counts " + std::to_string(nv) + " " + std::to_string(nf) +
           " exceed what the OFF reader takes (2147483647)");
    // CGAL doubles the edge count in an int.
    if (ne < -(1LL << 30) || ne >= (1LL << 30))
      fail("the header's edge count " + std::to_string(ne) + " is out of range; expected 0 to 1073741823");
    if (st_ && !c_)
      fail("texture coordinates without colours (" + std::string(h_ ? "4" : "") +
           "STOFF) are not read: CGAL's reader would index them from an unset offset; expected OFF, COFF, NOFF, "
           "CNOFF or STCOFF");
    const long long hom = h_ ? 1 : 0;
    const long long need = 3 + hom + (n_ ? 3 + hom : 0) + (st_ ? 2 + hom : 0);
    const std::size_t first_colour = std::size_t(3 + hom + (n_ ? 3 + hom : 0));
    std::vector<double> v;
    bool seen = false;
    // With colours a missing record is not reported first: CGAL reads a
    // colour from the empty record (fuzz_off, tests/data/regress/off-coff-truncated).
    const auto missing = [&](const char* what, long long k, long long of) {
      if (c_)
        fail("the file ends after " + std::to_string(k) + " of " + std::to_string(of) + " " + what +
             " (truncated file or bad counts?)");
    };
    for (long long k = 0; k < nv; ++k) {
      if (!record(v)) return missing("vertices", k, nv);  // without colours CGAL reports it
      if (!c_) continue;
      const std::string what = "vertex " + std::to_string(k);
      const long long count = static_cast<long long>(v.size()) - need;
      if (count < 0)
        fail(what + " has " + std::to_string(v.size()) + " numbers; expected at least " + std::to_string(need));
      colour_count(count, seen, what);
      if (count > 0) check_colour(v, first_colour, std::size_t(count), what);
    }
    seen = false;
    for (long long f = 0; f < nf; ++f) {
      if (!record(v)) return missing("faces", f, nf);
      if (v.empty()) continue;  // CGAL reports the malformed record
      const std::string what = "facet " + std::to_string(f);
      if (!(v[0] > -1 && v[0] <= double(size())))
        fail(what + " has vertex count " + num(v[0]) + "; expected an integer >= 3, at most the file's size");
      const std::size_t count = static_cast<std::size_t>(v[0]);
      for (std::size_t k = 1; k <= count && k < v.size(); ++k)
        if (!(v[k] > -1 && v[k] < 1e18))
          fail(what + " has vertex index " + num(v[k]) + "; expected an integer in [0, " + std::to_string(nv) + ")");
      if (!c_ || v.size() < count + 1) continue;  // a missing index: CGAL reports it
      const std::size_t colour = v.size() - count - 1;
      colour_count(static_cast<long long>(colour), seen, what);
      if (colour > 0) check_colour(v, count + 1, colour, what);
    }
  }

  // Binary OFF: big-endian int32 counts after the BINARY line, float vertex
  // records (CGAL reads no colours from them), then per facet an int32 count
  // and that many int32 indices. CGAL converts a negative count to a huge
  // std::size_t and resizes the facet to it; a count beyond the file's end
  // is refused too (CGAL would read the facet's indices from a failed stream).
  void binary(bool dim) {
    const auto int32 = [&](std::int64_t& out) {
      if (pos_ + 4 > size()) return false;
      const auto* u = reinterpret_cast<const unsigned char*>(text_.data() + pos_);
      out = std::int32_t(std::uint32_t(u[0]) << 24 | std::uint32_t(u[1]) << 16 | std::uint32_t(u[2]) << 8 | u[3]);
      pos_ += 4;
      return true;
    };
    std::int64_t d = 0, nv = 0, nf = 0, ne = 0;
    if ((dim && !int32(d)) || !int32(nv) || !int32(nf) || !int32(ne)) return;  // truncated: CGAL reports it
    const std::int64_t n = std::int64_t(size());
    if (nv < 0 || nf < 0 || ne < 0 || nv > n / 12 || nf > n / 4 || ne > n)
      fail("the binary header declares " + std::to_string(nv) + " vertices, " + std::to_string(nf) + " faces and " +
           std::to_string(ne) + " edges, impossible in a file of " + std::to_string(n) + " bytes");
    const std::int64_t hom = h_ ? 1 : 0;
    const std::int64_t floats = 3 + hom + (n_ ? 3 + hom : 0) + (st_ ? 2 + hom : 0);
    // CGAL does not check its stream after reading a binary number, so in a
    // truncated file it resizes a facet to an uninitialised count (fuzz_off,
    // tests/data/regress/off-binary-truncated): every record must be there.
    const auto truncated = [&](const std::string& what) {
      fail("the binary data end inside " + what + " (truncated file or bad counts?)");
    };
    if (std::uint64_t(nv) * std::uint64_t(4 * floats) > size() - pos_) truncated("the vertices");
    pos_ += std::size_t(nv * 4 * floats);
    for (std::int64_t f = 0; f < nf; ++f) {
      std::int64_t count = 0;
      if (!int32(count)) truncated("face " + std::to_string(f) + " of " + std::to_string(nf));
      if (count < 0 || count > std::int64_t(size() - pos_) / 4)
        fail("facet " + std::to_string(f) + " has vertex count " + std::to_string(count) +
             "; expected an integer >= 3, at most the indices left in the file");
      pos_ += std::size_t(count) * 4;
    }
  }

  std::string path_;
  std::string text_;
  std::size_t pos_ = 0;
  bool st_ = false, c_ = false, n_ = false, h_ = false;
};

}  // namespace

Mesh read_off(const std::string& path, std::vector<int>* polygon_sizes) {
  OffCheck(path).run();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("read_off: " + quote(path) + ": cannot open");
  std::vector<Point> pts;
  Polygons polys;
  if (!CGAL::IO::read_OFF(in, pts, polys, CGAL::parameters::verbose(false)))
    throw InputError("read_off: " + quote(path) +
                     ": malformed OFF (bad header, truncated data, bad number or vertex index out of range); "
                     "expected \"OFF\", the counts \"V F E\", V vertices and F faces");
  return mesh_from_polygons(to_vec3(pts), polys, "read_off", path, polygon_sizes);
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

Mesh read_obj(const std::string& path, std::vector<int>* polygon_sizes) {
  std::ifstream in(path);
  if (!in) throw IoError("read_obj: " + quote(path) + ": cannot open");
  std::vector<Point> pts;
  Polygons polys;
  if (!CGAL::IO::read_OBJ(in, pts, polys, CGAL::parameters::verbose(false)))
    throw InputError("read_obj: " + quote(path) +
                     ": malformed OBJ (unknown record, bad number, face index out of range, or no vertices or "
                     "faces); expected \"v x y z\" and \"f i j k ...\" records");
  return mesh_from_polygons(to_vec3(pts), polys, "read_obj", path, polygon_sizes);
}

void write_obj(const Mesh& m, const std::string& path, WorldFrame frame) {
  std::vector<Point> pts;
  Polygons polys;
  to_soup(m, pts, polys);
  std::ofstream os(path);
  os << "# frame " << frame_name(frame) << " SPACE=" << frame_name(frame) << "\n";
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
