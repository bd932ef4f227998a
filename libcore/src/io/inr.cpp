#include "pm/io/inr.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <map>
#include <sstream>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/gzip.h"
#include "pm/io/volume_header.h"

namespace fs = std::filesystem;

namespace pm {
namespace {

const char* const kWho = "read_inr";
constexpr std::size_t kBlock = 256;
constexpr std::size_t kMaxHeaderBlocks = 64;  // 16 KiB of header text at most
const char kMagic[] = "#INRIMAGE-4#{";
const char kEnd[] = "##}";

bool host_is_big_endian() {
  const std::uint16_t one = 1;
  unsigned char b;
  std::memcpy(&b, &one, 1);
  return b == 0;
}

std::string trim(const std::string& s) {
  std::size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
  return s.substr(a, b - a);
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

}  // namespace

Volume read_inr(const std::string& path) {
  const std::string where = std::string(kWho) + ": " + quote(path);
  const auto fail = [&](const std::string& what) -> void { throw InputError(where + ": " + what); };
  require_readable(path);
  GzipReader in(path, where);

  // Header: 256-byte blocks until one holds the "##}" line.
  std::string header;
  for (std::size_t b = 0;; ++b) {
    if (b == kMaxHeaderBlocks) fail("no \"##}\" header end in the first 16 KiB; expected an INRimage header");
    char block[kBlock];
    const std::size_t got = in.read(block, kBlock);
    header.append(block, got);
    if (b == 0 && header.compare(0, std::strlen(kMagic), kMagic) != 0)
      fail("does not start with \"#INRIMAGE-4#{\"; expected an INRimage file");
    if (got < kBlock) fail("truncated header: it ends before \"##}\"");
    if (header.find(std::string("\n") + kEnd) != std::string::npos) break;
  }

  std::map<std::string, std::string> kv;
  {
    std::istringstream lines(header.substr(std::strlen(kMagic)));
    std::string line;
    while (std::getline(lines, line)) {
      const std::string t = trim(line);
      if (t.rfind(kEnd, 0) == 0) break;
      if (t.empty() || t[0] == '#') continue;
      const auto eq = t.find('=');
      if (eq == std::string::npos) continue;
      kv[trim(t.substr(0, eq))] = trim(t.substr(eq + 1));
    }
  }
  const auto get = [&](const char* key) -> const std::string* {
    auto it = kv.find(key);
    return it == kv.end() ? nullptr : &it->second;
  };
  const auto number = [&](const char* key, double fallback) {
    const std::string* v = get(key);
    if (!v) return fallback;
    char* end = nullptr;
    const double d = std::strtod(v->c_str(), &end);
    if (end == v->c_str() || *end != '\0') fail(std::string(key) + " is \"" + *v + "\"; expected a number");
    return d;
  };
  const auto count = [&](const char* key, bool required) -> std::size_t {
    const std::string* v = get(key);
    if (!v) {
      if (required) fail(std::string("no ") + key + " in the header; expected " + key + "=<size>");
      return 1;
    }
    char* end = nullptr;
    const long long n = std::strtoll(v->c_str(), &end, 10);
    if (end == v->c_str() || *end != '\0' || n < 0)
      fail(std::string(key) + " is \"" + *v + "\"; expected an integer >= 1");
    return static_cast<std::size_t>(n);
  };

  const Dims dims{count("XDIM", true), count("YDIM", true), count("ZDIM", true)};
  if (const std::size_t vdim = count("VDIM", false); vdim != 1) {
    std::ostringstream m;
    m << "VDIM is " << vdim << "; expected 1 (scalar voxels)";
    fail(m.str());
  }

  // Voxel type from TYPE + PIXSIZE.
  const std::string type_s = get("TYPE") ? lower(*get("TYPE")) : std::string();
  const std::string pix_s = get("PIXSIZE") ? *get("PIXSIZE") : std::string();
  int bits = 0;
  {
    char* end = nullptr;
    bits = static_cast<int>(std::strtol(pix_s.c_str(), &end, 10));
    if (end == pix_s.c_str()) bits = 0;
  }
  VoxelType type = VoxelType::u8;
  bool ok = true;
  if (type_s == "unsigned fixed") {
    switch (bits) {
      case 8: type = VoxelType::u8; break;
      case 16: type = VoxelType::u16; break;
      case 32: type = VoxelType::u32; break;
      case 64: type = VoxelType::u64; break;
      default: ok = false;
    }
  } else if (type_s == "signed fixed") {
    switch (bits) {
      case 8: type = VoxelType::i8; break;
      case 16: type = VoxelType::i16; break;
      case 32: type = VoxelType::i32; break;
      case 64: type = VoxelType::i64; break;
      default: ok = false;
    }
  } else if (type_s == "float") {
    if (bits == 32) type = VoxelType::f32;
    else if (bits == 64) type = VoxelType::f64;
    else ok = false;
  } else {
    ok = false;
  }
  if (!ok)
    fail("TYPE=\"" + type_s + "\" with PIXSIZE=\"" + pix_s +
         "\" is not supported; expected unsigned fixed / signed fixed (8, 16, 32, 64 bits) or float (32, 64 bits)");

  bool big = false;
  if (const std::string* cpu = get("CPU")) {
    const std::string c = lower(*cpu);
    if (c == "decm" || c == "alpha" || c == "pc") big = false;
    else if (c == "sun" || c == "sgi" || c == "mips") big = true;
    else fail("CPU is \"" + *cpu + "\"; expected decm, alpha, pc (little endian) or sun, sgi (big endian)");
  }

  const double sp[3] = {number("VX", 1), number("VY", 1), number("VZ", 1)};
  for (int a = 0; a < 3; ++a) check_spacing(kWho, path, a, sp[a]);
  const Geometry g = Geometry::with_spacing(sp[0], sp[1], sp[2], {number("TX", 0), number("TY", 0), number("TZ", 0)});
  check_volume_header(kWho, path, dims, g);

  // Data size against the file before allocating.
  const std::uint64_t need = std::uint64_t(dims.count()) * voxel_size(type);
  std::error_code ec;
  const std::uint64_t file_bytes = fs::file_size(path, ec);
  std::ostringstream shape;
  shape << dims.nx << "x" << dims.ny << "x" << dims.nz << " " << voxel_type_name(type);
  if (!ec) {
    const std::uint64_t avail = file_bytes > header.size() ? file_bytes - header.size() : 0;
    if (!in.compressed() && avail < need) {
      std::ostringstream m;
      m << "truncated: expected " << need << " bytes of voxel data (" << shape.str() << ") after the "
        << header.size() << "-byte header, the file holds " << avail;
      fail(m.str());
    }
    if (in.compressed() && need > max_inflated_size(file_bytes)) {
      std::ostringstream m;
      m << "truncated or corrupt: header claims " << need << " bytes of voxel data (" << shape.str() << "), "
        << file_bytes << " gzip bytes can hold at most " << max_inflated_size(file_bytes);
      fail(m.str());
    }
  }
  Volume v(type, dims, g);
  const std::size_t got = in.read(v.raw(), v.byte_size());
  if (got != need) {
    std::ostringstream m;
    m << "truncated: expected " << need << " bytes of voxel data (" << shape.str() << "), got " << got;
    fail(m.str());
  }
  if (big != host_is_big_endian() && voxel_size(type) > 1) {
    auto* p = static_cast<unsigned char*>(v.raw());
    const std::size_t s = voxel_size(type);
    for (std::size_t i = 0; i < v.count(); ++i, p += s) std::reverse(p, p + s);
  }
  v.set_frame_source({"INR", "none", "INR has no world frame: coordinates taken as LPS", false});
  return v;
}

void write_inr(const Volume& v, const std::string& path) {
  const std::string where = "write_inr: " + quote(path);
  if (v.empty()) throw InputError(where + ": the volume is empty");
  // A flipped axis (negative step, e.g. x and y of a RAS NIfTI in LPS) is
  // stored reversed, so every voxel keeps its world position.
  Volume positive;
  try {
    positive = with_positive_steps(v, where);
  } catch (const InputError&) {
    throw InputError(where +
                     ": INRimage stores only per-axis spacing (VX VY VZ); the volume has oblique axes; "
                     "expected axis-aligned directions (write NRRD, MHA, NIfTI or VDB instead)");
  }
  const Volume* src = &positive;
  const Geometry& g = src->geometry();
  const Mat3& d = g.directions;
  const VoxelType t = src->type();
  const bool fl = !is_integer(t);
  const bool sgn = t == VoxelType::i8 || t == VoxelType::i16 || t == VoxelType::i32 || t == VoxelType::i64;
  std::ostringstream h;
  h << std::setprecision(17);
  h << kMagic << "\n";
  h << "XDIM=" << src->dims().nx << "\nYDIM=" << src->dims().ny << "\nZDIM=" << src->dims().nz << "\nVDIM=1\n";
  h << "TYPE=" << (fl ? "float" : (sgn ? "signed fixed" : "unsigned fixed")) << "\n";
  h << "PIXSIZE=" << voxel_size(t) * 8 << " bits\n";
  if (!fl) h << "SCALE=2**0\n";
  h << "CPU=" << (host_is_big_endian() ? "sun" : "decm") << "\n";
  h << "VX=" << d[0][0] << "\nVY=" << d[1][1] << "\nVZ=" << d[2][2] << "\n";
  h << "TX=" << g.origin.x << "\nTY=" << g.origin.y << "\nTZ=" << g.origin.z << "\n";
  std::string text = h.str();
  const std::string end = std::string(kEnd) + "\n";
  const std::size_t total = (text.size() + end.size() + kBlock - 1) / kBlock * kBlock;
  text.append(total - text.size() - end.size(), '\n');
  text += end;

  GzipWriter out(path, file_extension(path) == ".inr.gz", where);
  out.write(text.data(), text.size());
  out.write(src->raw(), src->byte_size());
  out.close();
}

}  // namespace pm
