// PLY reader and writer (see pm/io/ply.h).
#include "pm/io/ply.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/number_text.h"

namespace pm {

namespace {

enum class PlyType { i8, u8, i16, u16, i32, u32, f32, f64 };
enum class PlyFormat { ascii, binary_le, binary_be };

int type_size(PlyType t) {
  switch (t) {
    case PlyType::i8: case PlyType::u8: return 1;
    case PlyType::i16: case PlyType::u16: return 2;
    case PlyType::i32: case PlyType::u32: case PlyType::f32: return 4;
    case PlyType::f64: return 8;
  }
  return 1;
}

bool is_integral_type(PlyType t) { return t != PlyType::f32 && t != PlyType::f64; }

bool parse_type(const std::string& s, PlyType& t) {
  static const struct { const char* name; PlyType type; } kTypes[] = {
      {"char", PlyType::i8},     {"int8", PlyType::i8},     {"uchar", PlyType::u8},    {"uint8", PlyType::u8},
      {"short", PlyType::i16},   {"int16", PlyType::i16},   {"ushort", PlyType::u16},  {"uint16", PlyType::u16},
      {"int", PlyType::i32},     {"int32", PlyType::i32},   {"uint", PlyType::u32},    {"uint32", PlyType::u32},
      {"float", PlyType::f32},   {"float32", PlyType::f32}, {"double", PlyType::f64},  {"float64", PlyType::f64}};
  for (const auto& k : kTypes)
    if (s == k.name) {
      t = k.type;
      return true;
    }
  return false;
}

struct PlyProperty {
  std::string name;
  bool is_list = false;
  PlyType type = PlyType::f32;  // scalar type, or the type of list items
  PlyType count_type = PlyType::u8;  // lists only
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
  int find(const std::string& n) const {
    for (std::size_t i = 0; i < props.size(); ++i)
      if (props[i].name == n) return int(i);
    return -1;
  }
};

struct PlyHeader {
  PlyFormat format = PlyFormat::ascii;
  bool have_frame = false;
  WorldFrame frame = WorldFrame::lps;  // from a comment line
  std::vector<PlyElement> elements;
  std::size_t body = 0;  // byte offset of the first data byte
  std::size_t body_line = 0;  // line number of the first data line (ASCII)
};

std::vector<std::string> split_words(const std::string& line) {
  std::vector<std::string> w;
  std::istringstream is(line);
  std::string s;
  while (is >> s) w.push_back(s);
  return w;
}

bool parse_count(const std::string& s, std::uint64_t& v) {
  if (s.empty() || !std::isdigit(static_cast<unsigned char>(s[0]))) return false;
  errno = 0;
  char* end = nullptr;
  const unsigned long long x = std::strtoull(s.c_str(), &end, 10);
  if (errno != 0 || *end != '\0') return false;
  v = x;
  return true;
}

PlyHeader parse_header(const std::string& data, const std::string& path) {
  const std::string where = "read_ply: " + quote(path);
  PlyHeader h;
  std::size_t pos = 0, line_no = 0;
  bool have_format = false;
  auto next_line = [&](std::string& line) {
    if (pos >= data.size()) return false;
    std::size_t e = data.find('\n', pos);
    if (e == std::string::npos) e = data.size();
    line.assign(data, pos, e - pos);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    pos = std::min(data.size(), e + 1);
    ++line_no;
    return true;
  };
  std::string line;
  if (!next_line(line) || line != "ply")
    throw InputError(where + ": the file does not start with \"ply\"; expected a PLY file");
  for (;;) {
    if (!next_line(line))
      throw InputError(where + ": the header has no end_header line (truncated file?)");
    const auto w = split_words(line);
    const std::string at = where + ": header line " + std::to_string(line_no) + ": ";
    if (w.empty()) continue;
    const std::string& key = w[0];
    if (key == "end_header") break;
    if (key == "comment" || key == "obj_info") {
      if (!h.have_frame && key == "comment") h.have_frame = frame_from_comment(line, h.frame);
      continue;
    }
    if (key == "format") {
      if (w.size() != 3) throw InputError(at + "malformed format line; expected \"format <kind> 1.0\"");
      if (w[1] == "ascii") h.format = PlyFormat::ascii;
      else if (w[1] == "binary_little_endian") h.format = PlyFormat::binary_le;
      else if (w[1] == "binary_big_endian") h.format = PlyFormat::binary_be;
      else
        throw InputError(at + "unknown format " + quote(w[1]) +
                         "; expected ascii, binary_little_endian or binary_big_endian");
      have_format = true;
    } else if (key == "element") {
      PlyElement e;
      if (w.size() != 3 || !parse_count(w[2], e.count))
        throw InputError(at + "malformed element line " + quote(line) + "; expected \"element <name> <count>\"");
      e.name = w[1];
      for (const auto& other : h.elements)
        if (other.name == e.name) throw InputError(at + "element " + quote(e.name) + " is declared twice");
      h.elements.push_back(std::move(e));
    } else if (key == "property") {
      if (h.elements.empty()) throw InputError(at + "property before any element");
      PlyProperty p;
      if (w.size() == 5 && w[1] == "list") {
        p.is_list = true;
        if (!parse_type(w[2], p.count_type) || !parse_type(w[3], p.type))
          throw InputError(at + "unknown type in " + quote(line) +
                           "; expected char uchar short ushort int uint float double (or int8 ... float64)");
        if (!is_integral_type(p.count_type))
          throw InputError(at + "list count type " + quote(w[2]) + " is not an integer type");
        p.name = w[4];
      } else if (w.size() == 3) {
        if (!parse_type(w[1], p.type))
          throw InputError(at + "unknown type " + quote(w[1]) +
                           "; expected char uchar short ushort int uint float double (or int8 ... float64)");
        p.name = w[2];
      } else {
        throw InputError(at + "malformed property line " + quote(line) +
                         "; expected \"property <type> <name>\" or \"property list <type> <type> <name>\"");
      }
      if (h.elements.back().find(p.name) >= 0)
        throw InputError(at + "property " + quote(p.name) + " is declared twice in element " +
                         quote(h.elements.back().name));
      h.elements.back().props.push_back(std::move(p));
    } else {
      throw InputError(at + "unknown keyword " + quote(key) +
                       "; expected format, element, property, comment, obj_info or end_header");
    }
  }
  if (!have_format) throw InputError(where + ": the header has no format line");
  h.body = pos;
  h.body_line = line_no + 1;
  return h;
}

// A value for messages: "3", "0.5", "4e+09".
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

bool host_is_little_endian() {
  const std::uint16_t one = 1;
  unsigned char b;
  std::memcpy(&b, &one, 1);
  return b == 1;
}

// Reads values of the body one at a time, ASCII or binary.
class BodyReader {
 public:
  BodyReader(const std::string& data, const PlyHeader& h)
      : data_(data), pos_(h.body), line_(h.body_line), format_(h.format),
        swap_(h.format != PlyFormat::ascii && (h.format == PlyFormat::binary_le) != host_is_little_endian()) {}

  // false at the end of data or (ASCII) on a token that is not a number; see bad_token().
  bool read(PlyType t, double& v) {
    if (format_ == PlyFormat::ascii) {
      if (!read_ascii(v)) return false;
      if (t == PlyType::f32) v = double(float(v));  // the declared precision
      return true;
    }
    const int n = type_size(t);
    if (data_.size() - pos_ < std::size_t(n)) return false;
    unsigned char b[8];
    std::memcpy(b, data_.data() + pos_, n);
    pos_ += n;
    if (swap_) std::reverse(b, b + n);
    switch (t) {
      case PlyType::i8: { std::int8_t x; std::memcpy(&x, b, 1); v = x; break; }
      case PlyType::u8: { std::uint8_t x; std::memcpy(&x, b, 1); v = x; break; }
      case PlyType::i16: { std::int16_t x; std::memcpy(&x, b, 2); v = x; break; }
      case PlyType::u16: { std::uint16_t x; std::memcpy(&x, b, 2); v = x; break; }
      case PlyType::i32: { std::int32_t x; std::memcpy(&x, b, 4); v = x; break; }
      case PlyType::u32: { std::uint32_t x; std::memcpy(&x, b, 4); v = x; break; }
      case PlyType::f32: { float x; std::memcpy(&x, b, 4); v = x; break; }
      case PlyType::f64: { double x; std::memcpy(&x, b, 8); v = x; break; }
    }
    return true;
  }

  std::size_t remaining() const { return data_.size() - pos_; }
  const std::string& bad_token() const { return bad_token_; }
  // "line 12" (ASCII) or "byte 345" (binary): where the next value starts.
  std::string position() const {
    return format_ == PlyFormat::ascii ? "line " + std::to_string(line_) : "byte " + std::to_string(pos_);
  }

 private:
  bool read_ascii(double& v) {
    const char* s = data_.c_str();
    while (pos_ < data_.size() && std::isspace(static_cast<unsigned char>(s[pos_]))) {
      if (s[pos_] == '\n') ++line_;
      ++pos_;
    }
    if (pos_ >= data_.size()) return false;
    // Plain decimal numbers by std::from_chars (correctly rounded, like
    // strtod, at a fraction of the cost); anything else it does not take
    // whole (a leading '+', hexadecimal, "infinity") by strtod as before.
    const std::from_chars_result fc = std::from_chars(s + pos_, s + data_.size(), v);
    std::size_t e = std::size_t(fc.ptr - s);
    if (fc.ec != std::errc() || e == pos_ || (e < data_.size() && !std::isspace(static_cast<unsigned char>(s[e])))) {
      char* end = nullptr;
      v = std::strtod(s + pos_, &end);
      e = std::size_t(end - s);
    }
    if (e == pos_ || (e < data_.size() && !std::isspace(static_cast<unsigned char>(s[e])))) {
      std::size_t t = pos_;
      while (t < data_.size() && !std::isspace(static_cast<unsigned char>(s[t])) && t - pos_ < 32) ++t;
      bad_token_ = data_.substr(pos_, t - pos_);
      return false;
    }
    pos_ = e;
    return true;
  }

  const std::string& data_;
  std::size_t pos_, line_;
  PlyFormat format_;
  bool swap_;
  std::string bad_token_;
};

// Smallest number of bytes one record of `e` can take.
std::uint64_t min_record_bytes(const PlyElement& e, PlyFormat f) {
  std::uint64_t b = 0;
  for (const auto& p : e.props) {
    if (f == PlyFormat::ascii) b += 2;  // one token and a separator
    else b += std::uint64_t(type_size(p.is_list ? p.count_type : p.type));
  }
  return b;
}

std::string read_file_bytes(const std::string& path, const std::string& fn) {
  require_readable(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fn + ": " + quote(path) + ": cannot open");
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) throw IoError(fn + ": " + quote(path) + ": cannot determine the file size");
  in.seekg(0, std::ios::beg);
  std::string data(std::size_t(size), '\0');
  if (size > 0 && !in.read(&data[0], size)) throw IoError(fn + ": " + quote(path) + ": read failed");
  return data;
}

void check_property_name(const std::string& where, const char* kind, const std::string& n) {
  if (n.empty()) throw InputError(where + ": a " + kind + " property has an empty name; expected one word");
  for (char c : n)
    if (std::isspace(static_cast<unsigned char>(c)) || !std::isprint(static_cast<unsigned char>(c)))
      throw InputError(where + ": " + kind + " property name " + quote(n) +
                       " contains white space or control characters; expected one printable word");
}

}  // namespace

// Property names must be single words that do not clash with x y z (nx ny nz
// when the mesh has normals) or vertex_indices.
void check_ply_names(const Mesh& m, const std::string& where) {
  for (const auto& kv : m.vertex_scalars) {
    const std::string& n = kv.first;
    check_property_name(where, "vertex", n);
    if (n == "x" || n == "y" || n == "z" || (m.has_normals() && (n == "nx" || n == "ny" || n == "nz")))
      throw InputError(where + ": vertex property name " + quote(n) +
                       " is taken by positions or normals; expected another name");
  }
  for (const auto& kv : m.face_ints) {
    check_property_name(where, "face", kv.first);
    if (kv.first == "vertex_indices" || kv.first == "vertex_index")
      throw InputError(where + ": face property name " + quote(kv.first) + " is reserved; expected another name");
  }
}


Mesh read_ply(const std::string& path, WorldFrame* frame, std::vector<int>* polygon_sizes) {
  const std::string where = "read_ply: " + quote(path);
  const std::string data = read_file_bytes(path, "read_ply");
  const PlyHeader h = parse_header(data, path);

  // Fail fast on counts the file cannot hold, before allocating anything.
  const std::uint64_t remaining = data.size() - h.body;
  std::uint64_t needed = 0;
  for (const auto& e : h.elements) {
    const std::uint64_t rec = min_record_bytes(e, h.format);
    if (rec == 0 || e.count == 0) continue;
    const std::uint64_t slack = h.format == PlyFormat::ascii ? 1 : 0;  // last token needs no separator
    if (e.count > (remaining + slack) / rec || needed + e.count * rec > remaining + slack)
      throw InputError(where + ": the header declares " + std::to_string(e.count) + " " + e.name +
                       " elements needing at least " + std::to_string(rec) + " bytes each, but only " +
                       std::to_string(remaining) + " bytes follow the header (truncated file or bad count?)");
    needed += e.count * rec;
  }

  const PlyElement* vertex_el = nullptr;
  for (const auto& e : h.elements)
    if (e.name == "vertex") vertex_el = &e;
  const std::uint64_t nv = vertex_el ? vertex_el->count : 0;
  if (nv > std::uint64_t(INT_MAX))
    throw InputError(where + ": " + std::to_string(nv) + " vertices; expected at most " + std::to_string(INT_MAX));

  if (frame) *frame = h.frame;
  Mesh m;
  BodyReader r(data, h);
  for (const auto& e : h.elements) {
    auto fail = [&](std::uint64_t rec, const PlyProperty& p, const std::string& problem) -> InputError {
      return InputError(where + ": " + e.name + " " + std::to_string(rec) + ", property " + quote(p.name) + " (" +
                        r.position() + "): " + problem);
    };
    auto value = [&](std::uint64_t rec, const PlyProperty& p, PlyType t) {
      double v = 0;
      if (!r.read(t, v)) {
        if (!r.bad_token().empty()) throw fail(rec, p, quote(r.bad_token()) + " is not a number");
        throw fail(rec, p, "unexpected end of data; the header declares " + std::to_string(e.count) + " " +
                               e.name + " elements");
      }
      return v;
    };
    // Reads a list length and checks it against the data left.
    auto list_count = [&](std::uint64_t rec, const PlyProperty& p) {
      const double c = value(rec, p, p.count_type);
      const std::uint64_t item = h.format == PlyFormat::ascii ? 2 : std::uint64_t(type_size(p.type));
      if (!(c >= 0) || c != std::floor(c) || c > double(r.remaining() / item + 1))
        throw fail(rec, p, "list length " + num(c) + " is negative, fractional or longer than the " +
                               std::to_string(r.remaining()) + " bytes left");
      return std::uint64_t(c);
    };
    auto skip_record_prop = [&](std::uint64_t rec, const PlyProperty& p) {
      if (!p.is_list) {
        value(rec, p, p.type);
        return;
      }
      const std::uint64_t n = list_count(rec, p);
      for (std::uint64_t k = 0; k < n; ++k) value(rec, p, p.type);
    };

    if (e.count == 0) continue;
    if (&e == vertex_el) {
      const int ix = e.find("x"), iy = e.find("y"), iz = e.find("z");
      for (int i : {ix, iy, iz})
        if (i < 0 || e.props[i].is_list)
          throw InputError(where + ": the vertex element has no scalar properties x, y and z; expected all three");
      int in[3] = {e.find("nx"), e.find("ny"), e.find("nz")};
      const bool normals = in[0] >= 0 && in[1] >= 0 && in[2] >= 0 && !e.props[in[0]].is_list &&
                           !e.props[in[1]].is_list && !e.props[in[2]].is_list;
      // Destination per property: 0..2 position, 3..5 normal, 6 scalar, -1 skip.
      std::vector<int> dest(e.props.size(), -1);
      std::vector<std::vector<double>*> scalar(e.props.size(), nullptr);
      dest[ix] = 0; dest[iy] = 1; dest[iz] = 2;
      if (normals) { dest[in[0]] = 3; dest[in[1]] = 4; dest[in[2]] = 5; }
      m.vertices.resize(nv);
      if (normals) m.normals.resize(nv);
      for (std::size_t i = 0; i < e.props.size(); ++i)
        if (dest[i] < 0 && !e.props[i].is_list) {
          dest[i] = 6;
          auto& v = m.vertex_scalars[e.props[i].name];
          v.resize(nv);
          scalar[i] = &v;
        }
      for (std::uint64_t k = 0; k < nv; ++k)
        for (std::size_t i = 0; i < e.props.size(); ++i) {
          const PlyProperty& p = e.props[i];
          if (dest[i] < 0) {
            skip_record_prop(k, p);
            continue;
          }
          const double v = value(k, p, p.type);
          if (dest[i] < 3) m.vertices[k][dest[i]] = v;
          else if (dest[i] < 6) m.normals[k][dest[i] - 3] = v;
          else (*scalar[i])[k] = v;
        }
    } else if (e.name == "face") {
      int list = e.find("vertex_indices");
      if (list < 0) list = e.find("vertex_index");
      if (list < 0 || !e.props[list].is_list)
        throw InputError(where + ": the face element has no list property vertex_indices (or vertex_index); "
                                 "expected \"property list <count type> <index type> vertex_indices\"");
      std::vector<std::vector<int>*> ints(e.props.size(), nullptr);
      std::vector<int> values(e.props.size(), 0);
      for (std::size_t i = 0; i < e.props.size(); ++i)
        if (int(i) != list && !e.props[i].is_list) ints[i] = &m.face_ints[e.props[i].name];
      m.faces.reserve(e.count);
      if (polygon_sizes) polygon_sizes->clear();
      std::vector<int> poly;
      for (std::uint64_t k = 0; k < e.count; ++k) {
        poly.clear();
        for (std::size_t i = 0; i < e.props.size(); ++i) {
          const PlyProperty& p = e.props[i];
          if (int(i) == list) {
            const std::uint64_t n = list_count(k, p);
            if (n < 3)
              throw fail(k, p, "the face has " + std::to_string(n) + " vertices; expected at least 3");
            for (std::uint64_t c = 0; c < n; ++c) {
              const double v = value(k, p, p.type);
              if (!(v >= 0 && v < double(nv)) || v != std::floor(v))
                throw fail(k, p, "vertex index " + num(v) + " is out of range; expected an integer in [0, " +
                                     std::to_string(nv) + ")");
              poly.push_back(int(v));
            }
          } else if (ints[i]) {
            const double v = std::round(value(k, p, p.type));
            if (!(v >= double(INT_MIN) && v <= double(INT_MAX)))
              throw fail(k, p, "value " + num(v) + " does not fit an int");
            values[i] = int(v);
          } else {
            skip_record_prop(k, p);
          }
        }
        if (polygon_sizes) polygon_sizes->push_back(int(poly.size()));
        for (std::size_t c = 1; c + 1 < poly.size(); ++c) {
          m.faces.push_back({poly[0], poly[c], poly[c + 1]});
          for (std::size_t i = 0; i < e.props.size(); ++i)
            if (ints[i]) ints[i]->push_back(values[i]);
        }
      }
    } else if (!e.props.empty()) {  // records without properties take no bytes
      for (std::uint64_t k = 0; k < e.count; ++k)
        for (const auto& p : e.props) skip_record_prop(k, p);
    }
  }
  return m;
}

void write_ply(const Mesh& m, const std::string& path, bool binary_wanted, WorldFrame frame, bool doubles) {
  const std::string where = "write_ply: " + quote(path);
  m.validate(where);
  check_ply_names(m, where);
  const bool binary = binary_wanted && m.face_ints.empty();  // see ply.h: meshio

  std::string out;
  out += "ply\nformat ";
  out += binary ? "binary_little_endian 1.0\n" : "ascii 1.0\n";
  out += "comment written by particlemesh " PM_VERSION "\n";
  out += std::string("comment frame ") + frame_name(frame) + " SPACE=" + frame_name(frame) + "\n";
  out += "element vertex " + std::to_string(m.vertices.size()) + "\n";
  const std::string vt = doubles ? "property double " : "property float ";
  out += vt + "x\n" + vt + "y\n" + vt + "z\n";
  if (m.has_normals()) out += vt + "nx\n" + vt + "ny\n" + vt + "nz\n";
  for (const auto& kv : m.vertex_scalars) out += vt + kv.first + "\n";
  if (!m.faces.empty()) {
    out += "element face " + std::to_string(m.faces.size()) + "\n";
    out += "property list uchar int vertex_indices\n";
    for (const auto& kv : m.face_ints) out += "property int " + kv.first + "\n";
  }
  out += "end_header\n";

  const bool swap = !host_is_little_endian();
  auto put_bytes = [&](const void* p, std::size_t n) {
    unsigned char b[8];
    std::memcpy(b, p, n);
    if (swap) std::reverse(b, b + n);
    out.append(reinterpret_cast<const char*>(b), n);
  };
  auto put_float = [&](double v, bool last) {
    if (doubles) {
      if (binary) {
        put_bytes(&v, 8);
      } else {
        append_number(out, v);
        out += last ? '\n' : ' ';
      }
      return;
    }
    const float f = float(v);
    if (binary) {
      put_bytes(&f, 4);
    } else {
      append_number(out, double(f), kFloatDigits);
      out += last ? '\n' : ' ';
    }
  };
  auto put_int = [&](int v, bool last) {
    if (binary) {
      const std::int32_t x = v;
      put_bytes(&x, 4);
    } else {
      out += std::to_string(v);
      out += last ? '\n' : ' ';
    }
  };

  std::vector<const std::vector<double>*> scalars;
  for (const auto& kv : m.vertex_scalars) scalars.push_back(&kv.second);
  std::vector<const std::vector<int>*> ints;
  for (const auto& kv : m.face_ints) ints.push_back(&kv.second);
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const bool nrm = m.has_normals();
    for (int c = 0; c < 3; ++c) put_float(m.vertices[i][c], c == 2 && !nrm && scalars.empty());
    if (nrm)
      for (int c = 0; c < 3; ++c) put_float(m.normals[i][c], c == 2 && scalars.empty());
    for (std::size_t s = 0; s < scalars.size(); ++s) put_float((*scalars[s])[i], s + 1 == scalars.size());
  }
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    if (binary) {
      out += char(3);
    } else {
      out += "3 ";
    }
    for (int c = 0; c < 3; ++c) put_int(m.faces[f][c], c == 2 && ints.empty());
    for (std::size_t s = 0; s < ints.size(); ++s) put_int((*ints[s])[f], s + 1 == ints.size());
  }

  std::ofstream os(path, std::ios::binary);
  if (!os) throw IoError(where + ": cannot open for writing");
  os.write(out.data(), std::streamsize(out.size()));
  os.close();
  if (!os) throw IoError(where + ": write failed (disk full?)");
}

}  // namespace pm
