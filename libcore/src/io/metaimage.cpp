#include "pm/io/metaimage.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <sstream>
#include <utility>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/base/log.h"
#include "pm/io/gzip.h"
#include "pm/io/volume_header.h"

namespace fs = std::filesystem;

namespace pm {
namespace {

const char* const kWho = "read_metaimage";
constexpr std::size_t kMaxHeaderBytes = 1 << 20;

struct MetaType {
  const char* name;
  VoxelType type;
};
const MetaType kTypes[] = {
    {"MET_UCHAR", VoxelType::u8},        {"MET_CHAR", VoxelType::i8},       {"MET_USHORT", VoxelType::u16},
    {"MET_SHORT", VoxelType::i16},       {"MET_UINT", VoxelType::u32},      {"MET_INT", VoxelType::i32},
    {"MET_ULONG_LONG", VoxelType::u64},  {"MET_LONG_LONG", VoxelType::i64}, {"MET_FLOAT", VoxelType::f32},
    {"MET_DOUBLE", VoxelType::f64}};

const char* meta_type_name(VoxelType t) {
  for (const auto& m : kTypes)
    if (m.type == t) return m.name;
  return "?";
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(const std::string& s) {
  std::size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
  return s.substr(a, b - a);
}

bool host_is_big_endian() {
  const std::uint16_t one = 1;
  unsigned char b;
  std::memcpy(&b, &one, 1);
  return b == 0;
}

void swap_bytes(void* data, std::size_t count, std::size_t size) {
  if (size == 1) return;
  auto* p = static_cast<unsigned char*>(data);
  for (std::size_t i = 0; i < count; ++i, p += size) std::reverse(p, p + size);
}

// Parsed header: keys lower-cased, in file order; data_offset is where the
// data start when ElementDataFile = LOCAL.
struct Header {
  std::map<std::string, std::string> kv;
  std::map<std::string, std::string> spelled;  // lower-case key -> key as written
  std::uint64_t data_offset = 0;
};

class Parser {
 public:
  explicit Parser(const std::string& path) : path_(path), where_(std::string(kWho) + ": " + quote(path)) {}

  [[noreturn]] void fail(const std::string& what) const { throw InputError(where_ + ": " + what); }

  Header read_header() const {
    // The header is text ending with the ElementDataFile line; look for it in
    // the first kMaxHeaderBytes so a binary file cannot make us read it all.
    std::ifstream in(path_, std::ios::binary);
    if (!in) throw IoError(where_ + ": cannot open: " + std::strerror(errno));
    // Sized by the file, not the cap: a 1 MiB buffer per call was most of
    // the time spent on small files (seen in fuzz_metaimage's profile).
    // A stream that cannot seek (a pipe) reads up to the cap.
    in.seekg(0, std::ios::end);
    const std::streamoff file_bytes = in ? static_cast<std::streamoff>(in.tellg()) : -1;
    in.clear();
    in.seekg(0, std::ios::beg);
    in.clear();
    const std::size_t want = file_bytes >= 0 ? static_cast<std::size_t>(file_bytes) : kMaxHeaderBytes;
    std::string buf(want < kMaxHeaderBytes ? want : kMaxHeaderBytes, '\0');
    if (!buf.empty()) in.read(&buf[0], static_cast<std::streamsize>(buf.size()));
    buf.resize(static_cast<std::size_t>(in.gcount()));
    Header h;
    std::size_t pos = 0, line_no = 0;
    while (pos < buf.size()) {
      std::size_t nl = buf.find('\n', pos);
      const bool last = nl == std::string::npos;
      if (last) {
        if (buf.size() == kMaxHeaderBytes) break;
        nl = buf.size();
      }
      const std::string t = trim(buf.substr(pos, nl - pos));
      pos = last ? nl : nl + 1;
      ++line_no;
      if (t.empty() || t[0] == '#') continue;
      const auto eq = t.find('=');
      if (eq == std::string::npos || eq == 0) {
        std::ostringstream m;
        m << "line " << line_no << " is not \"Key = Value\"; expected a MetaImage header";
        fail(m.str());
      }
      const std::string key = trim(t.substr(0, eq));
      h.kv[lower(key)] = trim(t.substr(eq + 1));
      h.spelled[lower(key)] = key;
      if (lower(key) == "elementdatafile") {
        h.data_offset = pos;
        return h;
      }
    }
    fail("no ElementDataFile line in the header; expected a MetaImage header ending with ElementDataFile");
  }

  const std::string* find(const Header& h, std::initializer_list<const char*> keys) const {
    for (const char* k : keys) {
      auto it = h.kv.find(lower(k));
      if (it != h.kv.end()) return &it->second;
    }
    return nullptr;
  }

  std::vector<double> numbers(const Header& h, const std::string& key, const std::string& value,
                              std::size_t n) const {
    std::vector<double> out;
    const char* s = value.c_str();
    while (true) {
      while (std::isspace(static_cast<unsigned char>(*s))) ++s;
      if (!*s) break;
      char* end = nullptr;
      const double d = std::strtod(s, &end);
      if (end == s) {
        out.clear();
        break;
      }
      out.push_back(d);
      s = end;
    }
    if (out.size() != n) {
      std::ostringstream m;
      m << h.spelled.at(lower(key)) << " is \"" << value << "\"; expected " << n << " numbers";
      fail(m.str());
    }
    return out;
  }

  bool boolean(const Header& h, const std::string& key, const std::string& value) const {
    const std::string v = lower(value);
    if (v == "true" || v == "1") return true;
    if (v == "false" || v == "0") return false;
    fail(h.spelled.at(lower(key)) + " is \"" + value + "\"; expected True or False");
  }

 private:
  std::string path_, where_;
};

std::uint64_t file_size(const std::string& p, const std::string& where) {
  std::error_code ec;
  const auto s = fs::file_size(p, ec);
  if (ec) throw IoError(where + ": cannot read the data file " + quote(p) + ": " + ec.message());
  return s;
}

// MetaImage AnatomicalOrientation (ITK's convention): one letter per axis
// naming the side the axis comes from, in the LPS world: R = the axis runs
// from right to left (+x), L (-x), A = anterior to posterior (+y), P (-y),
// I = inferior to superior (+z), S (-z).
Vec3 orientation_letter_direction(char c) {
  switch (c) {
    case 'R': return {1, 0, 0};
    case 'L': return {-1, 0, 0};
    case 'A': return {0, 1, 0};
    case 'P': return {0, -1, 0};
    case 'I': return {0, 0, 1};
    case 'S': return {0, 0, -1};
    default: return {0, 0, 0};
  }
}

// The code for three axis directions (LPS): the assignment of world axes to
// image axes with the largest total |cosine|, then the sign of each.
std::string orientation_code(const Mat3& directions) {
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  Vec3 d[3];
  for (int a = 0; a < 3; ++a) d[a] = normalized(directions.column(a));
  int best = 0;
  double best_sum = -1;
  for (int p = 0; p < 6; ++p) {
    double sum = 0;
    for (int a = 0; a < 3; ++a) sum += std::fabs(d[a][perms[p][a]]);
    if (sum > best_sum + 1e-12) best = p, best_sum = sum;
  }
  static const char pos[3] = {'R', 'A', 'I'}, neg[3] = {'L', 'P', 'S'};
  std::string code;
  for (int a = 0; a < 3; ++a) {
    const int w = perms[best][a];
    code += d[a][w] >= 0 ? pos[w] : neg[w];
  }
  return code;
}

// The AnatomicalOrientation value upper-cased when it is a full code (three
// letters of R/L, A/P, I/S, each pair once), else empty (unknown, e.g. "???").
std::string parse_orientation_code(const std::string& value) {
  std::string c;
  for (char ch : value)
    if (!std::isspace(static_cast<unsigned char>(ch))) c += static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  if (c.size() != 3) return {};
  bool seen[3] = {false, false, false};
  for (char ch : c) {
    const Vec3 d = orientation_letter_direction(ch);
    int w = d.x != 0 ? 0 : (d.y != 0 ? 1 : (d.z != 0 ? 2 : -1));
    if (w < 0 || seen[w]) return {};
    seen[w] = true;
  }
  return c;
}

}  // namespace

Volume read_metaimage(const std::string& path) {
  const std::string where = std::string(kWho) + ": " + quote(path);
  require_readable(path);
  Parser P(path);
  const Header h = P.read_header();

  if (const auto* o = P.find(h, {"ObjectType"}); o && lower(*o) != "image")
    P.fail("ObjectType is \"" + *o + "\"; expected Image");
  const std::string* nd = P.find(h, {"NDims"});
  if (!nd) P.fail("no NDims; expected NDims = 3");
  {
    const auto n = P.numbers(h, "NDims", *nd, 1)[0];
    if (n != 3) {
      std::ostringstream m;
      m << "expected 3 axes, got " << n;
      P.fail(m.str());
    }
  }
  const std::string* ds = P.find(h, {"DimSize"});
  if (!ds) P.fail("no DimSize; expected DimSize = nx ny nz");
  const auto dsz = P.numbers(h, "DimSize", *ds, 3);
  for (double d : dsz)
    if (!(d >= 0 && d == std::floor(d) && d < 1e15)) P.fail("DimSize is \"" + *ds + "\"; expected 3 integers >= 1");
  const Dims dims{static_cast<std::size_t>(dsz[0]), static_cast<std::size_t>(dsz[1]),
                  static_cast<std::size_t>(dsz[2])};

  const std::string* et = P.find(h, {"ElementType"});
  if (!et) P.fail("no ElementType; expected e.g. ElementType = MET_UCHAR");
  VoxelType type = VoxelType::u8;
  bool known = false;
  for (const auto& m : kTypes)
    if (*et == m.name) type = m.type, known = true;
  if (!known) {
    std::string list;
    for (const auto& m : kTypes) list += std::string(list.empty() ? "" : " ") + m.name;
    P.fail("unknown ElementType " + *et + "; expected one of " + list);
  }
  if (const auto* c = P.find(h, {"ElementNumberOfChannels"}); c && P.numbers(h, "ElementNumberOfChannels", *c, 1)[0] != 1)
    P.fail("ElementNumberOfChannels is " + *c + "; expected 1 (scalar voxels)");
  if (const auto* b = P.find(h, {"BinaryData"}); b && !P.boolean(h, "BinaryData", *b))
    P.fail("BinaryData is False (ASCII voxels); expected binary data");
  bool msb = false;
  if (const auto* b = P.find(h, {"BinaryDataByteOrderMSB", "ElementByteOrderMSB"}))
    msb = P.boolean(h, h.kv.count("binarydatabyteordermsb") ? "BinaryDataByteOrderMSB" : "ElementByteOrderMSB", *b);
  bool compressed = false;
  if (const auto* c = P.find(h, {"CompressedData"})) compressed = P.boolean(h, "CompressedData", *c);

  // Geometry.
  double sp[3] = {1, 1, 1};
  if (const auto* s = P.find(h, {"ElementSpacing"})) {
    const auto v = P.numbers(h, "ElementSpacing", *s, 3);
    std::copy(v.begin(), v.end(), sp);
  } else if (const auto* s2 = P.find(h, {"ElementSize"})) {
    const auto v = P.numbers(h, "ElementSize", *s2, 3);
    std::copy(v.begin(), v.end(), sp);
  }
  for (int a = 0; a < 3; ++a) check_spacing(kWho, path, a, sp[a]);
  Geometry g;
  for (const char* k : {"Offset", "Position", "Origin"}) {
    if (const auto* o = P.find(h, {k})) {
      const auto v = P.numbers(h, k, *o, 3);
      g.origin = {v[0], v[1], v[2]};
      break;
    }
  }
  // World frame: MetaImage is LPS (ITK). AnatomicalOrientation gives the
  // axis directions when there is no TransformMatrix; with one, the matrix
  // wins and a disagreeing code is reported.
  FrameSource frame{"MetaImage", "LPS", "", true};
  std::string code;
  if (const auto* ao = P.find(h, {"AnatomicalOrientation"})) {
    code = parse_orientation_code(*ao);
    if (!code.empty()) frame.space = "LPS (AnatomicalOrientation " + code + ")";
  }
  Vec3 axis_dir[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  if (!code.empty())
    for (int a = 0; a < 3; ++a) axis_dir[a] = orientation_letter_direction(code[std::size_t(a)]);
  bool have_matrix = false;
  for (const char* k : {"TransformMatrix", "Rotation", "Orientation"}) {
    if (const auto* t = P.find(h, {k})) {
      const auto v = P.numbers(h, k, *t, 9);
      for (int a = 0; a < 3; ++a) {
        // MetaIO: elements [3a, 3a+2] are the direction of axis a.
        const Vec3 d{v[3 * a], v[3 * a + 1], v[3 * a + 2]};
        if (!(norm(d) > 0) || !is_finite(d)) {
          std::ostringstream m;
          m << k << " row " << a << " is (" << d.x << " " << d.y << " " << d.z << "); expected a non-zero direction";
          P.fail(m.str());
        }
        axis_dir[a] = normalized(d);
      }
      have_matrix = true;
      break;
    }
  }
  g.directions = Mat3::from_columns(axis_dir[0] * sp[0], axis_dir[1] * sp[1], axis_dir[2] * sp[2]);
  check_volume_header(kWho, path, dims, g);
  if (have_matrix && !code.empty() && orientation_code(g.directions) != code)
    warn(where + ": AnatomicalOrientation " + code + " disagrees with the TransformMatrix (" +
         orientation_code(g.directions) + "); using the TransformMatrix");

  // Where the data are.
  const std::string* edf = P.find(h, {"ElementDataFile"});
  std::string data_path;
  std::uint64_t offset = 0;
  const std::uint64_t need = std::uint64_t(dims.count()) * voxel_size(type);
  if (lower(*edf) == "local") {
    data_path = path;
    offset = h.data_offset;
  } else {
    if (lower(*edf) == "list" || lower(edf->substr(0, 5)) == "list " || edf->find('%') != std::string::npos)
      P.fail("ElementDataFile \"" + *edf + "\" (a list of slice files) is not supported; expected LOCAL or one file name");
    if (edf->empty()) P.fail("ElementDataFile is empty; expected LOCAL or a file name");
    const fs::path df(*edf);
    data_path = df.is_absolute() ? df.string() : (fs::path(path).parent_path() / df).string();
    try {
      require_readable(data_path);
    } catch (const IoError& e) {
      throw IoError(where + ": data file " + e.what());
    }
    if (const auto* hs = P.find(h, {"HeaderSize"})) {
      const double s = P.numbers(h, "HeaderSize", *hs, 1)[0];
      if (s == -1) {
        if (compressed) P.fail("HeaderSize = -1 with CompressedData; expected uncompressed data");
        const std::uint64_t total = file_size(data_path, where);
        if (total < need) {
          std::ostringstream m;
          m << "truncated: expected " << need << " bytes of voxel data in " << quote(data_path) << ", it has "
            << total;
          P.fail(m.str());
        }
        offset = total - need;
      } else if (s >= 0 && s == std::floor(s)) {
        offset = static_cast<std::uint64_t>(s);
      } else {
        P.fail("HeaderSize is " + *hs + "; expected a byte count >= 0 or -1");
      }
    }
  }
  const std::uint64_t total = file_size(data_path, where);
  const std::uint64_t avail = total > offset ? total - offset : 0;

  Volume v;
  std::ifstream in(data_path, std::ios::binary);
  if (!in) throw IoError(where + ": cannot open the data file " + quote(data_path));
  in.seekg(static_cast<std::streamoff>(offset));
  std::ostringstream shape;
  shape << dims.nx << "x" << dims.ny << "x" << dims.nz << " " << meta_type_name(type);
  if (!compressed) {
    if (avail < need) {
      std::ostringstream m;
      m << "truncated: expected " << need << " bytes of voxel data (" << shape.str() << "), "
        << (data_path == path ? std::string("the file") : quote(data_path)) << " holds " << avail;
      P.fail(m.str());
    }
    v = Volume(type, dims, g);
    in.read(static_cast<char*>(v.raw()), static_cast<std::streamsize>(need));
    if (static_cast<std::uint64_t>(in.gcount()) != need) {
      std::ostringstream m;
      m << "truncated: read " << in.gcount() << " of " << need << " bytes of voxel data";
      P.fail(m.str());
    }
  } else {
    // CompressedDataSize only flags truncation: the stream itself says where
    // it ends, and some writers understate it (VTK's frogtissue.mhd).
    const std::uint64_t csize = avail;
    if (const auto* cs = P.find(h, {"CompressedDataSize"})) {
      const double c = P.numbers(h, "CompressedDataSize", *cs, 1)[0];
      if (!(c > 0 && c == std::floor(c))) P.fail("CompressedDataSize is " + *cs + "; expected a byte count > 0");
      if (c > double(avail)) {
        std::ostringstream m;
        m << "truncated: CompressedDataSize is " << *cs << " bytes, the file holds " << avail;
        P.fail(m.str());
      }
    }
    if (need > max_inflated_size(csize)) {
      std::ostringstream m;
      m << "truncated or corrupt: header claims " << need << " bytes of voxel data (" << shape.str() << "), "
        << csize << " compressed bytes can hold at most " << max_inflated_size(csize);
      P.fail(m.str());
    }
    std::vector<unsigned char> packed(static_cast<std::size_t>(csize));
    in.read(reinterpret_cast<char*>(packed.data()), static_cast<std::streamsize>(csize));
    if (static_cast<std::uint64_t>(in.gcount()) != csize) P.fail("cannot read the compressed voxel data");
    v = Volume(type, dims, g);
    const std::size_t got = inflate_buffer(packed.data(), packed.size(), v.raw(), v.byte_size(), where);
    if (got != need) {
      std::ostringstream m;
      m << "truncated: the compressed data inflate to " << got << " bytes; expected " << need << " ("
        << shape.str() << ")";
      P.fail(m.str());
    }
  }
  if (msb != host_is_big_endian()) swap_bytes(v.raw(), v.count(), voxel_size(type));
  v.set_frame_source(std::move(frame));
  return v;
}

std::string mhd_data_path(const std::string& header_path, bool compress) {
  const fs::path p(header_path);
  const std::string name = p.filename().string();
  const std::string stem = name.substr(0, name.size() - file_extension(header_path).size());
  return (p.parent_path() / (stem + (compress ? ".zraw" : ".raw"))).string();
}

namespace {

std::string header_text(const Volume& v, bool compress, std::size_t compressed_size, const std::string& data_name) {
  const Geometry& g = v.geometry();
  std::ostringstream o;
  o << std::setprecision(17);
  o << "ObjectType = Image\nNDims = 3\nBinaryData = True\n";
  o << "BinaryDataByteOrderMSB = " << (host_is_big_endian() ? "True" : "False") << "\n";
  o << "CompressedData = " << (compress ? "True" : "False") << "\n";
  if (compress) o << "CompressedDataSize = " << compressed_size << "\n";
  o << "TransformMatrix =";
  for (int a = 0; a < 3; ++a) {
    const Vec3 d = normalized(g.directions.column(a));
    o << " " << d.x << " " << d.y << " " << d.z;
  }
  o << "\nOffset = " << g.origin.x << " " << g.origin.y << " " << g.origin.z << "\n";
  o << "CenterOfRotation = 0 0 0\n";
  o << "AnatomicalOrientation = " << orientation_code(g.directions) << "\n";
  o << "ElementSpacing = " << g.spacing(0) << " " << g.spacing(1) << " " << g.spacing(2) << "\n";
  o << "DimSize = " << v.dims().nx << " " << v.dims().ny << " " << v.dims().nz << "\n";
  o << "ElementType = " << meta_type_name(v.type()) << "\n";
  o << "ElementDataFile = " << data_name << "\n";
  return o.str();
}

}  // namespace

void write_metaimage_detached(const Volume& v, const std::string& header_path, const std::string& data_path,
                              const std::string& data_name, bool compress) {
  const std::string where = "write_metaimage: " + quote(header_path);
  std::vector<unsigned char> packed;
  if (compress) packed = deflate_buffer(v.raw(), v.byte_size());
  {
    GzipWriter data(data_path, false, "write_metaimage: " + quote(data_path));
    if (compress) data.write(packed.data(), packed.size());
    else data.write(v.raw(), v.byte_size());
    data.close();
  }
  GzipWriter out(header_path, false, where);
  const std::string text = header_text(v, compress, packed.size(), data_name);
  out.write(text.data(), text.size());
  out.close();
}

void write_metaimage(const Volume& v, const std::string& path, bool compress) {
  const std::string where = "write_metaimage: " + quote(path);
  if (v.empty()) throw InputError(where + ": the volume is empty");
  const std::string ext = file_extension(path);
  if (ext == ".mhd") {
    const std::string data = mhd_data_path(path, compress);
    write_metaimage_detached(v, path, data, fs::path(data).filename().string(), compress);
    return;
  }
  std::vector<unsigned char> packed;
  if (compress) packed = deflate_buffer(v.raw(), v.byte_size());
  GzipWriter out(path, false, where);
  const std::string text = header_text(v, compress, packed.size(), "LOCAL");
  out.write(text.data(), text.size());
  if (compress) out.write(packed.data(), packed.size());
  else out.write(v.raw(), v.byte_size());
  out.close();
}

}  // namespace pm
