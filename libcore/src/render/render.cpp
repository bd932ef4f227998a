#include "pm/render/render.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <unordered_map>

#include "pm/base/error.h"

namespace pm {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr float kFar = std::numeric_limits<float>::infinity();

// Viridis-like perceptual colormap: control points sampled along the curve.
Vec3 colormap(double t) {
  static const Vec3 kStops[] = {{0.267, 0.005, 0.329}, {0.283, 0.141, 0.458}, {0.254, 0.265, 0.530},
                                {0.207, 0.372, 0.553}, {0.164, 0.471, 0.558}, {0.128, 0.567, 0.551},
                                {0.135, 0.659, 0.518}, {0.267, 0.749, 0.441}, {0.478, 0.821, 0.318},
                                {0.741, 0.873, 0.150}, {0.993, 0.906, 0.144}};
  constexpr int n = int(sizeof kStops / sizeof kStops[0]);
  if (!std::isfinite(t)) return {0.5, 0.5, 0.5};
  t = std::clamp(t, 0.0, 1.0) * (n - 1);
  const int i = std::min(int(t), n - 2);
  const double f = t - i;
  return kStops[i] * (1 - f) + kStops[i + 1] * f;
}

}  // namespace

// Categorical palette for integer labels (value modulo 12).
Vec3 category_color(int v) {
  static const Vec3 kPalette[] = {{0.122, 0.467, 0.706}, {1.000, 0.498, 0.055}, {0.173, 0.627, 0.173},
                                  {0.839, 0.153, 0.157}, {0.580, 0.404, 0.741}, {0.549, 0.337, 0.294},
                                  {0.890, 0.467, 0.761}, {0.650, 0.850, 0.950}, {0.737, 0.741, 0.133},
                                  {0.090, 0.745, 0.812}, {0.950, 0.850, 0.250}, {0.600, 0.900, 0.500}};
  constexpr int n = int(sizeof kPalette / sizeof kPalette[0]);
  if (v >= 0 && v < n) return kPalette[v];
  // Beyond the palette (and for negative values): hue by the golden angle, three
  // lightness levels, converted from HSV.
  const unsigned u = unsigned(v < 0 ? -(long(v) + 1) + n : long(v));
  const double hue = std::fmod(0.1 + 0.618033988749895 * double(u), 1.0) * 6;
  const double sat = 0.55 + 0.15 * double(u % 2), val = 0.95 - 0.2 * double((u / 2) % 3);
  const int sector = int(hue) % 6;
  const double f = hue - std::floor(hue), p = val * (1 - sat), q = val * (1 - sat * f), t = val * (1 - sat * (1 - f));
  switch (sector) {
    case 0: return {val, t, p};
    case 1: return {q, val, p};
    case 2: return {p, val, t};
    case 3: return {p, q, val};
    case 4: return {t, p, val};
    default: return {val, p, q};
  }
}

namespace {

const Vec3 kPlain{0.80, 0.78, 0.72};
const Vec3 kEdge{0.12, 0.12, 0.15};

struct Shader {
  Vec3 light;  // unit, towards the light
  explicit Shader(const Camera& c) : light(normalized(-c.forward + 0.6 * c.up - 0.4 * c.right)) {}
  // Lambert + ambient; n faces the camera (or is zero: ambient + half).
  Vec3 operator()(const Vec3& n, const Vec3& base) const {
    const double ln = norm2(n) > 0 ? std::max(0.0, dot(n, light)) : 0.5;
    return base * (0.28 + 0.72 * ln);
  }
};

// Where the colour comes from.
struct ColorSource {
  const std::vector<double>* scalar = nullptr;  // per vertex
  const std::vector<int>* label = nullptr;      // per face
  double lo = 0, hi = 1;
  double t(double v) const { return hi > lo ? (v - lo) / (hi - lo) : 0.5; }
};

std::string available_properties(const Mesh& m) {
  std::string s;
  for (const auto& kv : m.vertex_scalars) s += (s.empty() ? "" : ", ") + kv.first + " (vertex)";
  for (const auto& kv : m.face_ints) s += (s.empty() ? "" : ", ") + kv.first + " (face)";
  return s.empty() ? "none" : s;
}

ColorSource color_source(const Mesh& m, const std::string& name) {
  ColorSource c;
  if (name.empty()) return c;
  if (auto it = m.vertex_scalars.find(name); it != m.vertex_scalars.end()) {
    c.scalar = &it->second;
    c.lo = std::numeric_limits<double>::infinity();
    c.hi = -c.lo;
    for (double v : it->second)
      if (std::isfinite(v)) {
        c.lo = std::min(c.lo, v);
        c.hi = std::max(c.hi, v);
      }
    if (c.lo > c.hi) c.lo = c.hi = 0;
    return c;
  }
  if (auto it = m.face_ints.find(name); it != m.face_ints.end()) {
    c.label = &it->second;
    return c;
  }
  throw InputError("render: no vertex or face property " + quote(name) + "; available: " + available_properties(m));
}

// "x", "y:0.3": axis index and fraction; throws UsageError otherwise.
std::pair<int, double> parse_clip(const std::string& c) {
  const std::string axis = c.substr(0, c.find(':'));
  double f = 0.5;
  bool ok = axis == "x" || axis == "y" || axis == "z";
  if (ok && c.size() > 1) {
    ok = c[1] == ':';
    if (ok) {
      std::size_t used = 0;
      try {
        f = std::stod(c.substr(2), &used);
      } catch (const std::exception&) {
        used = 0;
      }
      ok = used > 0 && used == c.size() - 2 && f >= 0 && f <= 1;
    }
  }
  if (!ok) throw UsageError("render: clip " + quote(c) + "; expected x, y or z, optionally :F with F in [0, 1]");
  return {axis[0] - 'x', f};
}

// 5x7 bitmap glyphs for legend text (bit 4 = leftmost column).
const std::uint8_t* glyph(char ch) {
  static const std::uint8_t kDigits[10][7] = {
      {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}, {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E},
      {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}, {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E},
      {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}, {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E},
      {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}, {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08},
      {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}, {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}};
  static const std::uint8_t kDash[7] = {0, 0, 0, 0x1F, 0, 0, 0};
  static const std::uint8_t kPlus[7] = {0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0};
  static const std::uint8_t kBlank[7] = {0, 0, 0, 0, 0, 0, 0};
  if (ch >= '0' && ch <= '9') return kDigits[ch - '0'];
  return ch == '-' ? kDash : ch == '+' ? kPlus : kBlank;
}

void fill_rect(Image& img, int x0, int y0, int w, int h, const Vec3& c) {
  for (int y = std::max(0, y0); y < std::min(img.height, y0 + h); ++y)
    for (int x = std::max(0, x0); x < std::min(img.width, x0 + w); ++x)
      for (int k = 0; k < 3; ++k)
        img.rgb[3 * (std::size_t(y) * std::size_t(img.width) + std::size_t(x)) + k] =
            std::uint8_t(std::lround(255.0 * std::clamp(c[k], 0.0, 1.0)));
}

void draw_text(Image& img, int x, int y, int scale, const std::string& text, const Vec3& c) {
  for (char ch : text) {
    const std::uint8_t* g = glyph(ch);
    for (int r = 0; r < 7; ++r)
      for (int col = 0; col < 5; ++col)
        if (g[r] & (0x10 >> col)) fill_rect(img, x + col * scale, y + r * scale, scale, scale, c);
    x += 6 * scale;
  }
}

// The key of a face-int colouring: one swatch and name per value present, top left.
void draw_legend(Image& img, const Mesh& m, const std::vector<int>& cat) {
  std::map<int, std::string> names;
  const auto a = m.face_ints.find("label_a"), b = m.face_ints.find("label_b");
  const bool pairs = a != m.face_ints.end() && b != m.face_ints.end() && &cat != &a->second && &cat != &b->second;
  for (std::size_t f = 0; f < cat.size(); ++f)
    if (!names.count(cat[f]))
      names[cat[f]] = pairs ? std::to_string(a->second[f]) + "-" + std::to_string(b->second[f])
                            : std::to_string(cat[f]);
  const int s = std::max(1, std::min(img.width, img.height) / 400);  // glyph pixel size
  const int row = 10 * s, pad = 4 * s;
  std::size_t longest = 0;
  for (const auto& [v, n] : names) longest = std::max(longest, n.size());
  // Columns top to bottom, left to right, as many as fit in half the image's
  // width; what does not fit ends in "+N" (N more entries).
  const int per_col = std::max(1, (img.height - 2 * pad) / row);
  const int col_w = 8 * s + 3 * s + int(std::max<std::size_t>(longest, 4)) * 6 * s + pad;
  const int max_cols = std::max(1, (img.width / 2 - pad) / col_w);
  const int total = int(names.size());
  const int cols = std::min(max_cols, (total + per_col - 1) / per_col);
  const int capacity = cols * per_col;
  const int shown_n = total <= capacity ? total : capacity - 1;
  const int rows = std::min(per_col, std::max(total, 1));
  fill_rect(img, 0, 0, pad + cols * col_w, pad + rows * row + pad - 3 * s, {1, 1, 1});
  int k = 0;
  for (const auto& [v, n] : names) {
    const int x = pad + (k / per_col) * col_w, y = pad + (k % per_col) * row;
    if (k == shown_n) {
      draw_text(img, x, y, s, "+" + std::to_string(total - shown_n), kEdge);
      break;
    }
    fill_rect(img, x, y, 8 * s, 7 * s, category_color(v));
    draw_text(img, x + 11 * s, y, s, n, kEdge);
    ++k;
  }
}

void check_params(const RenderParams& p) {
  if (!p.clip.empty()) parse_clip(p.clip);
  if (p.width < 1 || p.width > 8192 || p.height < 1 || p.height > 8192)
    throw UsageError("render: image size " + std::to_string(p.width) + "x" + std::to_string(p.height) +
                     " pixels; expected each side in [1, 8192]");
  if (p.up != "x" && p.up != "y" && p.up != "z")
    throw UsageError("render: up axis " + quote(p.up) + "; expected x, y or z");
  if (p.mode != "auto" && p.mode != "disks" && p.mode != "splats" && p.mode != "mesh")
    throw UsageError("render: mode " + quote(p.mode) + "; expected auto, disks, splats or mesh");
  if (!(p.radius >= 0) || !std::isfinite(p.radius))
    throw UsageError("render: radius " + std::to_string(p.radius) + "; expected >= 0 (0 = auto)");
  if (!std::isfinite(p.azimuth_deg) || !std::isfinite(p.elevation_deg))
    throw UsageError("render: camera angles must be finite");
}

// Frame buffers shared by all modes.
struct Frame {
  int w, h;
  std::vector<float> depth;
  std::vector<Vec3> color;
  Frame(int w_, int h_) : w(w_), h(h_), depth(std::size_t(w_) * h_, kFar), color(std::size_t(w_) * h_) {}
  std::size_t at(int x, int y) const { return std::size_t(y) * std::size_t(w) + std::size_t(x); }

  Image to_image(const Vec3& background) const {
    Image img(w, h);
    for (std::size_t i = 0; i < depth.size(); ++i) {
      const Vec3 c = depth[i] < kFar ? color[i] : background;
      for (int k = 0; k < 3; ++k)
        img.rgb[3 * i + k] = std::uint8_t(std::lround(255.0 * std::clamp(c[k], 0.0, 1.0)));
    }
    return img;
  }
};

// ---------------------------------------------------------------------------
// Triangles

void render_mesh(const Mesh& m, const Camera& cam, const ColorSource& cs, bool edges, Frame& fb,
                 const std::vector<std::uint8_t>* edge_flags) {
  const Shader shade(cam);
  std::vector<Vec3> s(m.vertices.size());
  for (std::size_t i = 0; i < s.size(); ++i) s[i] = cam.project(m.vertices[i]);
  const bool smooth = m.has_normals();
  for (std::size_t f = 0; f < m.faces.size(); ++f) {
    const auto& t = m.faces[f];
    const Vec3 &a = s[t[0]], &b = s[t[1]], &c = s[t[2]];
    if (!is_finite(a) || !is_finite(b) || !is_finite(c)) continue;
    // Signed doubled area in screen space; either winding is drawn.
    const double area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (std::fabs(area) < 1e-12) continue;
    const int x0 = std::max(0, int(std::floor(std::min({a.x, b.x, c.x}))));
    const int x1 = std::min(fb.w - 1, int(std::ceil(std::max({a.x, b.x, c.x}))));
    const int y0 = std::max(0, int(std::floor(std::min({a.y, b.y, c.y}))));
    const int y1 = std::min(fb.h - 1, int(std::ceil(std::max({a.y, b.y, c.y}))));
    if (x0 > x1 || y0 > y1) continue;

    Vec3 fn = cross(m.vertices[t[1]] - m.vertices[t[0]], m.vertices[t[2]] - m.vertices[t[0]]);
    fn = normalized(dot(fn, cam.forward) > 0 ? -fn : fn);
    Vec3 flat_base = kPlain;
    if (cs.label) flat_base = category_color((*cs.label)[f]);
    // Edge lengths (pixels) to turn edge functions into distances.
    // Hidden edges (fan diagonals) get an inverse length of 0: never near.
    const std::uint8_t drawn = edge_flags ? (*edge_flags)[f] : 7;
    constexpr double kFar = 1e300;
    const double ila = drawn & 2 ? 1 / std::hypot(c.x - b.x, c.y - b.y) : 0.0,
                 ilb = drawn & 4 ? 1 / std::hypot(a.x - c.x, a.y - c.y) : 0.0,
                 ilc = drawn & 1 ? 1 / std::hypot(b.x - a.x, b.y - a.y) : 0.0;
    const double inv = 1.0 / area;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5, py = y + 0.5;
        const double ea = (c.x - b.x) * (py - b.y) - (c.y - b.y) * (px - b.x);  // opposite a
        const double eb = (a.x - c.x) * (py - c.y) - (a.y - c.y) * (px - c.x);  // opposite b
        const double ec = (b.x - a.x) * (py - a.y) - (b.y - a.y) * (px - a.x);  // opposite c
        const double wa = ea * inv, wb = eb * inv, wc = ec * inv;
        if (wa < 0 || wb < 0 || wc < 0) continue;
        const double z = wa * a.z + wb * b.z + wc * c.z;
        const std::size_t i = fb.at(x, y);
        if (!(z < fb.depth[i])) continue;
        fb.depth[i] = float(z);
        Vec3 n = fn;
        if (smooth) {
          n = wa * m.normals[t[0]] + wb * m.normals[t[1]] + wc * m.normals[t[2]];
          n = normalized(dot(n, cam.forward) > 0 ? -n : n);
          if (norm2(n) == 0) n = fn;
        }
        Vec3 base = flat_base;
        if (cs.scalar)
          base = colormap(cs.t(wa * (*cs.scalar)[t[0]] + wb * (*cs.scalar)[t[1]] + wc * (*cs.scalar)[t[2]]));
        Vec3 col = shade(n, base);
        if (edges) {
          const double d = std::min({ila > 0 ? std::fabs(ea) * ila : kFar, ilb > 0 ? std::fabs(eb) * ilb : kFar,
                                     ilc > 0 ? std::fabs(ec) * ilc : kFar});
          const double k = std::clamp(1.1 - d, 0.0, 1.0) * 0.85;
          col = col * (1 - k) + kEdge * k;
        }
        fb.color[i] = col;
      }
  }
}

// ---------------------------------------------------------------------------
// Points: disks and splats

// A point's disk of radius r (world units) in screen space. Calls f(pixel
// index, squared distance from the centre in world units, depth) for every
// pixel centre the disk covers.
struct DiskRaster {
  const Camera& cam;
  template <class F>
  void operator()(const Vec3& p, const Vec3& n, double r, int w, int h, F&& f) const {
    const Vec3 c = cam.project(p);
    if (!is_finite(c)) return;
    const double nr = dot(n, cam.right), nu = dot(n, cam.up);
    double nf = dot(n, cam.forward);
    if (std::fabs(nf) < 1e-3) nf = nf < 0 ? -1e-3 : 1e-3;
    const double ex = r * cam.scale * std::sqrt(std::max(0.0, 1 - nr * nr));
    const double ey = r * cam.scale * std::sqrt(std::max(0.0, 1 - nu * nu));
    const int x0 = std::max(0, int(std::floor(c.x - ex))), x1 = std::min(w - 1, int(std::floor(c.x + ex)));
    const int y0 = std::max(0, int(std::floor(c.y - ey))), y1 = std::min(h - 1, int(std::floor(c.y + ey)));
    const double r2 = r * r, inv_s = 1.0 / cam.scale;
    for (int y = y0; y <= y1; ++y) {
      const double dy = -(y + 0.5 - c.y) * inv_s;  // along cam.up
      for (int x = x0; x <= x1; ++x) {
        const double dx = (x + 0.5 - c.x) * inv_s;  // along cam.right
        const double t = -(dx * nr + dy * nu) / nf;  // along cam.forward, in the disk's plane
        const double d2 = dx * dx + dy * dy + t * t;
        if (d2 <= r2) f(std::size_t(y) * std::size_t(w) + std::size_t(x), d2, c.z + t);
      }
    }
  }
};

// Unit normals of the points, taken as oriented (outward): from the mesh,
// else from its faces, else facing the camera. Points facing away from the
// camera get a zero vector: they are not drawn (back-face culling keeps the
// far side from showing through at silhouettes).
std::vector<Vec3> point_normals(const Mesh& m, const Camera& cam) {
  std::vector<Vec3> n(m.vertices.size(), -cam.forward);
  if (m.has_normals() || !m.faces.empty()) {
    Mesh tmp;
    if (!m.has_normals()) {
      tmp.vertices = m.vertices;
      tmp.faces = m.faces;
      compute_vertex_normals(tmp);
    }
    const std::vector<Vec3>& src = m.has_normals() ? m.normals : tmp.normals;
    for (std::size_t i = 0; i < n.size(); ++i) {
      const Vec3 v = normalized(src[i]);
      if (norm2(v) > 0) n[i] = dot(v, cam.forward) > 0 ? Vec3{} : v;
    }
  }
  return n;
}

void render_disks(const Mesh& m, const Camera& cam, const ColorSource& cs, const std::vector<double>& r,
                  Frame& fb) {
  const Shader shade(cam);
  const std::vector<Vec3> n = point_normals(m, cam);
  const DiskRaster raster{cam};
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    if (norm2(n[i]) == 0) continue;
    const Vec3 col = shade(n[i], cs.scalar ? colormap(cs.t((*cs.scalar)[i])) : kPlain);
    raster(m.vertices[i], n[i], r[i], fb.w, fb.h, [&](std::size_t px, double, double z) {
      if (z < fb.depth[px]) {
        fb.depth[px] = float(z);
        fb.color[px] = col;
      }
    });
  }
}

// Surface splatting (SPEC §3.8): a visibility pass finds the front-most
// surface per pixel; an accumulation pass blends the Gaussian-weighted normals
// and values of every splat within its radius of that depth; normalised and shaded.
void render_splats(const Mesh& m, const Camera& cam, const ColorSource& cs, const std::vector<double>& r,
                   Frame& fb) {
  const Shader shade(cam);
  const std::vector<Vec3> n = point_normals(m, cam);
  const DiskRaster raster{cam};
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    if (norm2(n[i]) == 0) continue;
    raster(m.vertices[i], n[i], r[i], fb.w, fb.h, [&](std::size_t px, double, double z) {
      if (z < fb.depth[px]) fb.depth[px] = float(z);
    });
  }
  const std::size_t np = fb.depth.size();
  std::vector<float> wsum(np, 0.f), vsum(cs.scalar ? np : 0, 0.f);
  std::vector<Vec3> nsum(np);
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    if (norm2(n[i]) == 0) continue;
    const double v = cs.scalar ? (*cs.scalar)[i] : 0.0;
    const bool finite = std::isfinite(v);
    const double tol = r[i], k = -2.0 / (r[i] * r[i]);  // Gaussian with sigma = r/2
    raster(m.vertices[i], n[i], r[i], fb.w, fb.h, [&](std::size_t px, double d2, double z) {
      if (z > fb.depth[px] + tol) return;
      const double wt = std::exp(k * d2);
      wsum[px] += float(wt);
      nsum[px] += wt * n[i];
      if (cs.scalar && finite) vsum[px] += float(wt * v);
    });
  }
  for (std::size_t px = 0; px < np; ++px) {
    if (!(fb.depth[px] < kFar) || wsum[px] <= 0) continue;
    const Vec3 nn = normalized(nsum[px]);
    const Vec3 base = cs.scalar ? colormap(cs.t(vsum[px] / wsum[px])) : kPlain;
    fb.color[px] = shade(nn, base);
  }
}

// Auto radius: this factor times the distance to the kNeighbors-th nearest
// neighbour (about the local spacing, so adaptive samples stay hole-free).
constexpr int kNeighbors = 6;
constexpr double kDiskFactor = 0.9, kSplatFactor = 1.0;

// Radius per point, world units: `fixed` when > 0, else factor × local
// spacing (clamped to [0.25, 4] × its mean; `fallback` when unknown).
std::vector<double> point_radii(const std::vector<Vec3>& pts, double fixed, double factor, double fallback) {
  std::vector<double> r(pts.size(), fixed);
  if (fixed <= 0) {
    const int k = int(std::min<std::size_t>(kNeighbors, pts.empty() ? 1 : pts.size() - 1));
    const std::vector<double> d = nearest_neighbor_distances(pts, std::max(k, 1));
    double sum = 0;
    std::size_t count = 0;
    for (double x : d)
      if (x > 0) {
        sum += x;
        ++count;
      }
    const double mean = count ? sum / double(count) : fallback;
    for (std::size_t i = 0; i < pts.size(); ++i)
      r[i] = factor * (d[i] > 0 ? std::clamp(d[i], 0.25 * mean, 4 * mean) : mean);
  }
  return r;
}

// What render() draws with: the resolved mode, the camera and, for points,
// the radius of each disk.
struct Setup {
  std::string mode;
  Camera cam;
  std::vector<double> radii;
};

Setup setup(const Mesh& m, const RenderParams& p) {
  check_params(p);
  m.validate("render");
  if (m.vertices.empty()) throw InputError("render: the mesh has no vertices; expected at least one");
  Setup s;
  s.mode = p.mode;
  if (s.mode == "auto") s.mode = m.faces.empty() ? "splats" : "mesh";
  if (s.mode == "mesh" && m.faces.empty())
    throw InputError("render: mode \"mesh\" needs faces; the input has none (use disks or splats)");
  double margin = 0;
  if (s.mode != "mesh") {
    Box box;
    for (const Vec3& v : m.vertices)
      if (is_finite(v)) box.extend(v);
    s.radii = point_radii(m.vertices, p.radius, s.mode == "splats" ? kSplatFactor : kDiskFactor,
                          0.01 * norm(box.size()));
    for (double r : s.radii) margin = std::max(margin, r);
  }
  s.cam = fit_camera(m.vertices, p, margin);
  // Never smaller than about a pixel, so every point shows.
  for (double& r : s.radii) r = std::max(r, 0.75 / s.cam.scale);
  return s;
}

}  // namespace

Camera fit_camera(const std::vector<Vec3>& points, const RenderParams& p, double margin) {
  check_params(p);
  Box box;
  for (const Vec3& v : points)
    if (is_finite(v)) box.extend(v);
  Camera c;
  c.width = p.width;
  c.height = p.height;
  c.center = box.empty() ? Vec3{} : 0.5 * (box.lo + box.hi);
  double r2 = 0;
  for (const Vec3& v : points)
    if (is_finite(v)) r2 = std::max(r2, norm2(v - c.center));
  double radius = std::sqrt(r2) + std::max(0.0, margin);
  if (!(radius > 0) || !std::isfinite(radius)) radius = 1;
  c.scale = std::min(p.width, p.height) / (2 * 1.05 * radius);
  // Horizontal basis (a, b) and up axis u, right-handed.
  Vec3 a{1, 0, 0}, b{0, 1, 0}, u{0, 0, 1};
  if (p.up == "y") { a = {0, 0, 1}; b = {1, 0, 0}; u = {0, 1, 0}; }
  if (p.up == "x") { a = {0, 1, 0}; b = {0, 0, 1}; u = {1, 0, 0}; }
  const double az = p.azimuth_deg * kPi / 180, el = p.elevation_deg * kPi / 180;
  const Vec3 eye = std::cos(el) * (std::cos(az) * a + std::sin(az) * b) + std::sin(el) * u;
  c.forward = normalized(-eye);
  c.right = normalized(-std::sin(az) * a + std::cos(az) * b);
  if (std::cos(el) < 0) c.right = -c.right;  // past the pole: keep up pointing up
  c.up = cross(c.right, c.forward);
  return c;
}

std::vector<double> nearest_neighbor_distances(const std::vector<Vec3>& pts, int k) {
  const std::size_t n = pts.size();
  std::vector<double> out(n, 0.0);
  if (n < 2 || k < 1) return out;
  Box box;
  for (const Vec3& p : pts)
    if (is_finite(p)) box.extend(p);
  if (box.empty()) return out;
  const double diag = norm(box.size());
  if (!(diag > 0)) return out;
  // Cells about twice the spacing of a surface sample (diag / sqrt(n)), so the
  // k nearest are usually within one ring; grown when most points find too
  // few neighbours within three rings (volume-filling or sparse sets).
  double h = 2 * diag / std::sqrt(double(n));
  const std::int64_t lim = std::int64_t(1) << 21;
  for (int attempt = 0; attempt < 8; ++attempt, h *= 3) {
    if (diag / h > double(lim / 2)) h = diag / double(lim / 2);
    auto cell = [&](const Vec3& p, int a) { return std::int64_t(std::floor((p[a] - box.lo[a]) / h)); };
    auto key = [](std::int64_t x, std::int64_t y, std::int64_t z) {
      return (std::uint64_t(x) << 42) | (std::uint64_t(y) << 21) | std::uint64_t(z);
    };
    std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
    order.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
      if (is_finite(pts[i])) order.emplace_back(key(cell(pts[i], 0), cell(pts[i], 1), cell(pts[i], 2)), std::uint32_t(i));
    std::sort(order.begin(), order.end());
    std::unordered_map<std::uint64_t, std::pair<std::uint32_t, std::uint32_t>> grid;
    grid.reserve(order.size());
    for (std::size_t i = 0; i < order.size();) {
      std::size_t j = i;
      while (j < order.size() && order[j].first == order[i].first) ++j;
      grid.emplace(order[i].first, std::make_pair(std::uint32_t(i), std::uint32_t(j - i)));
      i = j;
    }
    constexpr int kRings = 3;
    std::vector<double> best;  // k smallest squared distances, ascending
    std::size_t found = 0;
    std::fill(out.begin(), out.end(), 0.0);
    for (const auto& entry : order) {
      const Vec3& p = pts[entry.second];
      const std::int64_t cx = cell(p, 0), cy = cell(p, 1), cz = cell(p, 2);
      best.assign(std::size_t(k), std::numeric_limits<double>::infinity());
      for (int ring = 0; ring <= kRings; ++ring) {
        for (std::int64_t dz = -ring; dz <= ring; ++dz)
          for (std::int64_t dy = -ring; dy <= ring; ++dy)
            for (std::int64_t dx = -ring; dx <= ring; ++dx) {
              if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring) continue;
              const std::int64_t x = cx + dx, y = cy + dy, z = cz + dz;
              if (x < 0 || y < 0 || z < 0 || x >= lim || y >= lim || z >= lim) continue;
              const auto it = grid.find(key(x, y, z));
              if (it == grid.end()) continue;
              const std::uint32_t b = it->second.first, e = b + it->second.second;
              for (std::uint32_t q = b; q < e; ++q) {
                const double d2 = norm2(pts[order[q].second] - p);
                if (d2 > 0 && d2 < best.back()) {
                  std::size_t at = best.size() - 1;
                  while (at > 0 && best[at - 1] > d2) {
                    best[at] = best[at - 1];
                    --at;
                  }
                  best[at] = d2;
                }
              }
            }
        // Anything in further rings is at least ring * h away.
        if (best.back() <= (ring * h) * (ring * h)) break;
      }
      if (best.back() < std::numeric_limits<double>::infinity()) {
        out[entry.second] = std::sqrt(best.back());
        ++found;
      }
    }
    if (found * 10 >= order.size() * 9) return out;
  }
  return out;
}

double mean_nearest_neighbor_distance(const std::vector<Vec3>& pts) {
  double sum = 0;
  std::size_t count = 0;
  for (double d : nearest_neighbor_distances(pts, 1))
    if (d > 0) {
      sum += d;
      ++count;
    }
  return count ? sum / double(count) : 0;
}

Camera render_camera(const Mesh& m, const RenderParams& p) { return setup(m, p).cam; }

ClipPlane clip_plane(const std::vector<Vec3>& points, const RenderParams& p, const Camera& cam) {
  const auto [axis, frac] = parse_clip(p.clip);
  Box box;
  for (const Vec3& v : points)
    if (is_finite(v)) box.extend(v);
  ClipPlane c;
  c.axis = axis;
  c.position = box.empty() ? 0.0 : box.lo[axis] + frac * (box.hi[axis] - box.lo[axis]);
  c.removed_side = -cam.forward[axis] >= 0 ? 1.0 : -1.0;  // the camera sits on the + side
  return c;
}

std::vector<std::uint8_t> polygon_edge_flags(const std::vector<int>& polygon_sizes, std::size_t faces) {
  std::vector<std::uint8_t> flags;
  flags.reserve(faces);
  for (const int n : polygon_sizes)
    for (int k = 1; k + 1 < n; ++k)  // triangle (v0, vk, vk+1): its middle edge is a polygon side
      flags.push_back(std::uint8_t(2 | (k == 1 ? 1 : 0) | (k == n - 2 ? 4 : 0)));
  if (flags.size() != faces)
    throw InputError("polygon_edge_flags: the polygons give " + std::to_string(flags.size()) + " triangles for " +
                     std::to_string(faces) + " faces; expected the same count");
  return flags;
}

Image render(const Mesh& m, const RenderParams& p, const std::vector<std::uint8_t>* edge_flags) {
  if (edge_flags && edge_flags->size() != m.faces.size())
    throw InputError("render: " + std::to_string(edge_flags->size()) + " edge flags for " +
                     std::to_string(m.faces.size()) + " faces; expected one per face");
  const Setup s = setup(m, p);
  const ColorSource cs = color_source(m, p.color_by);
  if (cs.label && s.mode != "mesh")
    throw InputError("render: face property " + quote(p.color_by) +
                     " can only colour mode \"mesh\"; expected a vertex property");
  Frame fb(p.width, p.height);
  if (s.mode == "mesh" && !p.clip.empty()) {
    // Drop the faces on the camera's side of the plane; face properties follow.
    const ClipPlane cp = clip_plane(m.vertices, p, s.cam);
    const int axis = cp.axis;
    Mesh kept;
    std::vector<std::uint8_t> kept_flags;
    kept.vertices = m.vertices;
    kept.normals = m.normals;
    kept.vertex_scalars = m.vertex_scalars;
    for (const auto& [name, vals] : m.face_ints) kept.face_ints[name];
    for (std::size_t f = 0; f < m.faces.size(); ++f) {
      const auto& t = m.faces[f];
      const double c = (m.vertices[t[0]][axis] + m.vertices[t[1]][axis] + m.vertices[t[2]][axis]) / 3;
      if ((c - cp.position) * cp.removed_side > 0) continue;
      kept.faces.push_back(t);
      if (edge_flags) kept_flags.push_back((*edge_flags)[f]);
      for (const auto& [name, vals] : m.face_ints) kept.face_ints[name].push_back(vals[f]);
    }
    const ColorSource kcs = color_source(kept, p.color_by);
    render_mesh(kept, s.cam, kcs, p.edges, fb, edge_flags ? &kept_flags : nullptr);
  } else if (s.mode == "mesh") render_mesh(m, s.cam, cs, p.edges, fb, edge_flags);
  else if (s.mode == "disks") render_disks(m, s.cam, cs, s.radii, fb);
  else render_splats(m, s.cam, cs, s.radii, fb);
  Image img = fb.to_image(p.background);
  if (p.legend && cs.label) draw_legend(img, m, *cs.label);
  return img;
}

}  // namespace pm
