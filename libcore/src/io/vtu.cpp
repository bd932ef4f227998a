// VTK XML UnstructuredGrid reader (see pm/io/vtu.h).
#include "pm/io/vtu.h"

#include <tinyxml2.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <map>
#include <set>
#include <vector>

#include "pm/base/error.h"
#include "pm/io/gzip.h"
#include "scan.h"
#include "vtk_cells.h"

namespace pm {
namespace {

using tinyxml2::XMLElement;

int base64_value(unsigned char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

// Base64 to bytes. Whitespace is skipped; '=' padding may end a run in the
// middle (VTK and meshio encode a compressed array's header and data as two
// runs), decoding goes on with the next run.
std::string base64_decode(const char* s, std::size_t n, const std::string& what) {
  std::string out;
  out.reserve(n / 4 * 3 + 3);
  int quad[4], k = 0, pad = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (std::isspace(c)) continue;
    if (c == '=') {
      if (k < 2) throw InputError(what + ": misplaced '=' in base64 data at character " + std::to_string(i));
      quad[k++] = 0;
      ++pad;
    } else {
      const int v = base64_value(c);
      if (v < 0 || pad > 0)
        throw InputError(what + ": character " + std::to_string(i) + " (" + std::to_string(int(c)) +
                         ") is not base64; expected A-Z a-z 0-9 + / =");
      quad[k++] = v;
    }
    if (k == 4) {
      const std::uint32_t w = std::uint32_t(quad[0]) << 18 | std::uint32_t(quad[1]) << 12 |
                              std::uint32_t(quad[2]) << 6 | std::uint32_t(quad[3]);
      out += char((w >> 16) & 0xff);
      if (pad < 2) out += char((w >> 8) & 0xff);
      if (pad < 1) out += char(w & 0xff);
      k = 0;
      pad = 0;
    }
  }
  if (k != 0) throw InputError(what + ": base64 data ends in the middle of a group (truncated?)");
  return out;
}

struct TypeInfo {
  int size = 0;
  bool is_float = false, is_signed = false;
};
TypeInfo type_info(const std::string& t) {
  static const std::map<std::string, TypeInfo> kTypes = {
      {"Int8", {1, false, true}},    {"UInt8", {1, false, false}},  {"Int16", {2, false, true}},
      {"UInt16", {2, false, false}}, {"Int32", {4, false, true}},   {"UInt32", {4, false, false}},
      {"Int64", {8, false, true}},   {"UInt64", {8, false, false}}, {"Float32", {4, true, true}},
      {"Float64", {8, true, true}},  {"Char", {1, false, true}},    {"String", {1, false, false}}};
  const auto it = kTypes.find(t);
  return it == kTypes.end() ? TypeInfo{} : it->second;
}

class VtuReader {
 public:
  VtuReader(const std::string& data, const std::string& where) : data_(data), where_(where) {}

  LabelledTets read(WorldFrame& frame) {
    split_appended();
    if (doc_.Parse(xml_.c_str(), xml_.size()) != tinyxml2::XML_SUCCESS)
      throw InputError(where_ + ": line " + std::to_string(doc_.ErrorLineNum()) + ": not well-formed XML (" +
                       std::string(doc_.ErrorName()) + "); expected a VTK XML file");
    frame_from_comments(frame);
    const XMLElement* root = doc_.FirstChildElement("VTKFile");
    if (!root) throw InputError(where_ + ": no <VTKFile> element; expected a VTK XML file");
    const char* type = root->Attribute("type");
    if (!type || std::string(type) != "UnstructuredGrid")
      throw InputError(where_ + ": VTKFile type " + quote(type ? type : "(none)") +
                       "; expected UnstructuredGrid (a tetrahedral mesh)");
    const char* order = root->Attribute("byte_order");
    big_ = order && std::string(order) == "BigEndian";
    if (const char* h = root->Attribute("header_type")) {
      if (std::string(h) == "UInt64") header_ = 8;
      else if (std::string(h) != "UInt32") fail(root, "header_type " + quote(h) + "; expected UInt32 or UInt64");
    }
    if (const char* c = root->Attribute("compressor")) {
      if (std::string(c) == "vtkZLibDataCompressor") zlib_ = true;
      else if (*c) fail(root, "compressor " + quote(c) + " is not read; expected none or vtkZLibDataCompressor");
    }
    const XMLElement* grid = root->FirstChildElement("UnstructuredGrid");
    if (!grid) fail(root, "no <UnstructuredGrid> element");
    collect_offsets(root);
    frame_from_field_data(grid, frame);
    std::vector<Vec3> points;
    vtk_cells::Cells cells;
    cells.begin.push_back(0);
    std::map<std::string, std::vector<double>> arrays;
    std::set<std::string> names;  // the union over pieces, so every piece can be checked
    int pieces = 0;
    for (const XMLElement* piece = grid->FirstChildElement("Piece"); piece;
         piece = piece->NextSiblingElement("Piece"), ++pieces) {
      const std::size_t np = count(piece, "NumberOfPoints"), nc = count(piece, "NumberOfCells");
      const std::size_t base = points.size();
      if (np > 0) {
        const XMLElement* pe = child(piece, "Points");
        const XMLElement* da = pe->FirstChildElement("DataArray");
        if (!da) fail(pe, "<Points> without a DataArray");
        const std::vector<double> xyz = values(da, "Points", 3, np);
        for (std::size_t i = 0; i < np; ++i) {
          const Vec3 p(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
          if (!is_finite(p)) fail(da, "point " + std::to_string(i) + " is not finite; expected finite coordinates");
          points.push_back(p);
        }
      }
      if (nc > 0) {
        const XMLElement* ce = child(piece, "Cells");
        const std::vector<double> offsets = values(named(ce, "offsets"), "offsets", 1, nc);
        const XMLElement* conn_e = named(ce, "connectivity");
        const double total = offsets.back();
        if (!(total >= 0 && total <= 1e12) || total != std::floor(total))
          fail(conn_e, "the last offset " + format_number(total) + " is not a connectivity size");
        const std::vector<double> conn = values(conn_e, "connectivity", 1, std::size_t(total));
        const std::vector<double> types = values(named(ce, "types"), "types", 1, nc);
        double prev = 0;
        for (std::size_t c = 0; c < nc; ++c) {
          if (!(offsets[c] >= prev && offsets[c] <= total) || offsets[c] != std::floor(offsets[c]))
            fail(named(ce, "offsets"), "offset " + std::to_string(c) + " is " + format_number(offsets[c]) +
                                           "; expected non-decreasing integers up to the last");
          prev = offsets[c];
          for (double v = c ? offsets[c - 1] : 0; v < offsets[c]; ++v) {
            const double x = conn[std::size_t(v)];
            cells.conn.push_back(x >= 0 ? x + double(base) : x);
          }
          cells.begin.push_back(cells.conn.size());
          if (!(types[c] >= 0 && types[c] <= 255))
            fail(named(ce, "types"), "cell " + std::to_string(c) + ": type " + format_number(types[c]) +
                                         "; expected a VTK cell type (0..255)");
          cells.types.push_back(int(types[c]));
        }
      }
      const XMLElement* cd = piece->FirstChildElement("CellData");
      std::set<std::string> here;
      for (const XMLElement* da = cd ? cd->FirstChildElement("DataArray") : nullptr; da;
           da = da->NextSiblingElement("DataArray")) {
        const char* name = da->Attribute("Name");
        const int comps = da->IntAttribute("NumberOfComponents", 1);
        if (!name || comps != 1 || !wanted(name)) continue;
        const std::vector<double> v = values(da, name, 1, nc);
        auto& dst = arrays[name];
        if (pieces > 0 && !names.count(name)) fail(da, std::string("cell array ") + quote(name) + " is missing in earlier pieces");
        dst.insert(dst.end(), v.begin(), v.end());
        names.insert(name);
        here.insert(name);
      }
      for (const auto& n : names)
        if (!here.count(n)) fail(piece, "piece " + std::to_string(pieces) + " lacks the cell array " + quote(n));
    }
    if (pieces == 0) fail(grid, "no <Piece>");
    return vtk_cells::to_tets(std::move(points), cells, arrays, where_);
  }

 private:
  [[noreturn]] void fail(const XMLElement* e, const std::string& what) const {
    throw InputError(where_ + ": line " + std::to_string(e ? e->GetLineNum() : 0) + ": " + what);
  }
  static bool wanted(const std::string& n) {
    return n == "material" || n == "gmsh:physical" || n == "medit:ref" || n == "label_a" || n == "label_b";
  }
  const XMLElement* child(const XMLElement* e, const char* name) const {
    const XMLElement* c = e->FirstChildElement(name);
    if (!c) fail(e, std::string("<") + e->Name() + "> without <" + name + ">");
    return c;
  }
  const XMLElement* named(const XMLElement* e, const std::string& name) const {
    for (const XMLElement* da = e->FirstChildElement("DataArray"); da; da = da->NextSiblingElement("DataArray"))
      if (const char* n = da->Attribute("Name"); n && name == n) return da;
    fail(e, "<" + std::string(e->Name()) + "> has no DataArray " + quote(name));
  }
  std::size_t count(const XMLElement* e, const char* attr) const {
    const char* v = e->Attribute(attr);
    char* end = nullptr;
    const double n = v ? std::strtod(v, &end) : -1;
    // Compressed arrays can hold up to 1032 bytes per byte of the file.
    if (!v || *end != '\0' || !(n >= 0 && n <= 1032.0 * double(data_.size())) || n != std::floor(n))
      fail(e, std::string(attr) + " " + quote(v ? v : "(none)") +
                  "; expected a count no larger than the file (truncated or corrupt?)");
    return std::size_t(n);
  }

  // The XML text without the appended data (which is not XML) and that data.
  void split_appended() {
    const std::size_t a = data_.find("<AppendedData");
    if (a == std::string::npos) {
      xml_ = data_;
      return;
    }
    const std::size_t gt = data_.find('>', a);
    const std::size_t us = gt == std::string::npos ? gt : data_.find('_', gt);
    if (us == std::string::npos)
      throw InputError(where_ + ": <AppendedData> without its '_' marker (truncated?)");
    std::size_t end = data_.rfind("</AppendedData>");
    if (end == std::string::npos || end < us) end = data_.size();
    xml_ = data_.substr(0, us) + data_.substr(end);
    if (end == data_.size()) xml_ += "</AppendedData></VTKFile>";
    app_begin_ = us + 1;
    app_end_ = end;
    const std::string tag = data_.substr(a, gt - a);
    base64_appended_ = tag.find("base64") != std::string::npos;
    have_appended_ = true;
  }
  void frame_from_comments(WorldFrame& frame) const {
    for (std::size_t p = xml_.find("<!--"); p != std::string::npos; p = xml_.find("<!--", p + 4)) {
      const std::size_t e = xml_.find("-->", p);
      if (frame_from_comment(xml_.substr(p, e == std::string::npos ? std::string::npos : e - p), frame)) return;
    }
  }
  void frame_from_field_data(const XMLElement* grid, WorldFrame& frame) {
    const XMLElement* fd = grid->FirstChildElement("FieldData");
    for (const XMLElement* a = fd ? fd->FirstChildElement() : nullptr; a; a = a->NextSiblingElement()) {
      const char* n = a->Attribute("Name");
      const char* f = a->Attribute("format");
      if (!n || std::string(n) != "SPACE" || !f || std::string(f) != "ascii" || !a->GetText()) continue;
      std::string s;
      for (const char* p = a->GetText(); *p;) {
        char* end = nullptr;
        const long c = std::strtol(p, &end, 10);
        if (end == p) break;
        if (c > 0 && c < 128) s += char(c);
        p = end;
      }
      frame_from_comment("SPACE=" + s, frame);
    }
  }
  // Offsets of every appended array, to find where each base64 block ends.
  void collect_offsets(const XMLElement* e) {
    for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
      if (const char* f = c->Attribute("format"); f && std::string(f) == "appended")
        if (const char* o = c->Attribute("offset")) offsets_.insert(std::strtoull(o, nullptr, 10));
      collect_offsets(c);
    }
  }

  std::uint64_t uint(const char* b, std::size_t at, int size) const {
    std::uint64_t u = 0;
    for (int k = 0; k < size; ++k)
      u |= std::uint64_t(static_cast<unsigned char>(b[at + std::size_t(big_ ? size - 1 - k : k)])) << (8 * k);
    return u;
  }

  // The raw bytes of a binary block (header + data, compressed or not) that starts at `block[0]`.
  std::string payload(const XMLElement* da, const std::string& s, const std::string& what) const {
    return payload(da, s.data(), s.size(), what);
  }
  std::string payload(const XMLElement* da, const char* block, std::size_t block_size, const std::string& what) const {
    const std::size_t h = std::size_t(header_);
    if (block_size < h) fail(da, what + ": the binary data ends inside its header (truncated?)");
    if (!zlib_) {
      const std::uint64_t n = uint(block, 0, header_);
      if (n > block_size - h)
        fail(da, what + ": " + std::to_string(n) + " bytes announced, " + std::to_string(block_size - h) +
                     " present (truncated?)");
      return std::string(block + h, std::size_t(n));
    }
    const std::uint64_t nb = uint(block, 0, header_);
    if (block_size < 3 * h || nb > (block_size - 3 * h) / h)
      fail(da, what + ": the compression header ends early (truncated?)");
    const std::uint64_t bs = uint(block, h, header_), last = uint(block, 2 * h, header_);
    std::size_t at = (3 + std::size_t(nb)) * h;
    std::uint64_t total = 0;
    std::vector<std::uint64_t> csize(nb);
    for (std::uint64_t i = 0; i < nb; ++i) {
      csize[i] = uint(block, (3 + std::size_t(i)) * h, header_);
      const std::uint64_t usize = (i + 1 == nb && last != 0) ? last : bs;
      if (csize[i] > block_size || usize > max_inflated_size(csize[i]))
        fail(da, what + ": compressed block " + std::to_string(i) + " sizes " + std::to_string(csize[i]) + " -> " +
                     std::to_string(usize) + " are not possible (corrupt?)");
      total += usize;
    }
    if (total > max_inflated_size(block_size)) fail(da, what + ": uncompressed size is not possible (corrupt?)");
    std::string out(std::size_t(total), '\0');
    std::size_t done = 0;
    for (std::uint64_t i = 0; i < nb; ++i) {
      const std::uint64_t usize = (i + 1 == nb && last != 0) ? last : bs;
      if (csize[i] > block_size - at)
        fail(da, what + ": compressed block " + std::to_string(i) + " ends after the data (truncated?)");
      const std::size_t got = inflate_buffer(block + at, std::size_t(csize[i]), &out[done], std::size_t(usize),
                                             where_ + ": " + what);
      if (got != usize)
        fail(da, what + ": block " + std::to_string(i) + " inflates to " + std::to_string(got) + " bytes; expected " +
                     std::to_string(usize) + " (truncated?)");
      at += std::size_t(csize[i]);
      done += std::size_t(usize);
    }
    return out;
  }

  // The values of a DataArray: `comps` components (checked) times `n` tuples.
  std::vector<double> values(const XMLElement* da, const std::string& name, int comps, std::size_t n) const {
    const std::string what = "DataArray " + quote(name);
    const char* type = da->Attribute("type");
    const TypeInfo ti = type_info(type ? type : "");
    if (ti.size == 0) fail(da, what + ": type " + quote(type ? type : "(none)") + " is not read");
    if (da->IntAttribute("NumberOfComponents", 1) != comps)
      fail(da, what + ": " + std::to_string(da->IntAttribute("NumberOfComponents", 1)) + " components; expected " +
                   std::to_string(comps));
    const std::size_t want = n * std::size_t(comps);
    const char* f = da->Attribute("format");
    const std::string format = f ? f : "ascii";
    std::vector<double> v;
    if (format == "ascii") {
      const char* p = da->GetText();
      if (want > data_.size() / 2 + 1)
        fail(da, what + ": " + std::to_string(want) + " values are more than the file holds (truncated or a bad count?)");
      v.reserve(want);
      while (p && v.size() < want) {
        while (*p && std::isspace(static_cast<unsigned char>(*p))) ++p;
        if (!*p) break;
        char* end = nullptr;
        const double x = std::strtod(p, &end);
        if (end == p || (*end && !std::isspace(static_cast<unsigned char>(*end))))
          fail(da, what + ": " + quote(std::string(p, std::min<std::size_t>(20, std::strlen(p)))) + " is not a number");
        v.push_back(x);
        p = end;
      }
      if (v.size() != want)
        fail(da, what + ": " + std::to_string(v.size()) + " values; expected " + std::to_string(want) + " (truncated?)");
      return v;
    }
    std::string bytes;
    if (format == "binary") {
      const char* t = da->GetText();
      bytes = payload(da, base64_decode(t ? t : "", t ? std::strlen(t) : 0, where_ + ": " + what), what);
    } else if (format == "appended") {
      if (!have_appended_) fail(da, what + ": format appended without <AppendedData>");
      const char* o = da->Attribute("offset");
      char* end = nullptr;
      const unsigned long long off = o ? std::strtoull(o, &end, 10) : 0;
      if (!o || *end != '\0' || off >= app_end_ - app_begin_)
        fail(da, what + ": offset " + quote(o ? o : "(none)") + " is outside the appended data (" +
                     std::to_string(app_end_ - app_begin_) + " bytes; truncated?)");
      const std::size_t b = app_begin_ + std::size_t(off);
      if (base64_appended_) {
        auto next = offsets_.upper_bound(off);
        const std::size_t e = next == offsets_.end() ? app_end_ : std::min(app_end_, app_begin_ + std::size_t(*next));
        bytes = payload(da, base64_decode(data_.data() + b, e - b, where_ + ": " + what), what);
      } else {
        bytes = payload(da, data_.data() + b, app_end_ - b, what);
      }
    } else {
      fail(da, what + ": format " + quote(format) + "; expected ascii, binary or appended");
    }
    if (bytes.size() != want * std::size_t(ti.size))
      fail(da, what + ": " + std::to_string(bytes.size()) + " bytes; expected " + std::to_string(want) + " values of " +
                   std::to_string(ti.size) + " bytes (truncated?)");
    v.resize(want);
    for (std::size_t i = 0; i < want; ++i) {
      const std::uint64_t u = uint(bytes.data(), i * std::size_t(ti.size), ti.size);
      if (ti.is_float && ti.size == 8) {
        std::memcpy(&v[i], &u, 8);
      } else if (ti.is_float) {
        const std::uint32_t w = std::uint32_t(u);
        float x;
        std::memcpy(&x, &w, 4);
        v[i] = x;
      } else if (ti.is_signed && ti.size < 8) {
        const std::uint64_t sign = std::uint64_t(1) << (8 * ti.size - 1);
        v[i] = double(std::int64_t(u ^ sign) - std::int64_t(sign));
      } else {
        v[i] = ti.is_signed ? double(std::int64_t(u)) : double(u);
      }
    }
    return v;
  }

  const std::string& data_;
  std::string where_, xml_;
  tinyxml2::XMLDocument doc_;
  bool big_ = false, zlib_ = false, have_appended_ = false, base64_appended_ = false;
  int header_ = 4;
  std::size_t app_begin_ = 0, app_end_ = 0;
  std::set<unsigned long long> offsets_;
};

}  // namespace

LabelledTets read_vtu(const std::string& path, WorldFrame* frame) {
  const std::string where = "read_vtu: " + quote(path);
  const std::string data = scan::slurp(path, where);
  WorldFrame fr = WorldFrame::lps;
  LabelledTets t = VtuReader(data, where).read(fr);
  if (frame) *frame = fr;
  return t;
}

}  // namespace pm
