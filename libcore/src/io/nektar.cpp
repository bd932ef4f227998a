#include "pm/io/nektar.h"

#include <tinyxml2.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <sys/stat.h>

#include "pm/base/error.h"
#include "pm/io/gzip.h"

namespace pm {
namespace {

constexpr const char* kCompressString = "B64Z-LittleEndian";
// Caps on what a file may make us allocate (far above any real mesh or field
// of this format; a corrupt count must not exhaust memory).
constexpr std::size_t kMaxInflated = std::size_t(1) << 31;
constexpr int kMaxModes = 20;  // the evaluator's limit (pm/field/hp_field.cpp)

std::string int_str(long long v) { return std::to_string(v); }

// ---- base64 + zlib -----------------------------------------------------------

int b64_value(unsigned char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

struct InflateGuard {
  z_stream* zs;
  ~InflateGuard() { inflateEnd(zs); }
};

// ---- small parsing helpers ---------------------------------------------------

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }

std::string trim(const std::string& s) {
  std::size_t a = 0, b = s.size();
  while (a < b && is_space(s[a])) ++a;
  while (b > a && is_space(s[b - 1])) --b;
  return s.substr(a, b - a);
}

// All text directly inside an element (several text nodes around comments).
std::string element_text(const tinyxml2::XMLElement* e) {
  std::string s;
  for (const tinyxml2::XMLNode* n = e->FirstChild(); n; n = n->NextSibling()) {
    if (const tinyxml2::XMLText* t = n->ToText()) {
      s += t->Value();
      s += ' ';
    }
  }
  return s;
}

bool parse_int(const std::string& s, long long& v) {
  const std::string t = trim(s);
  if (t.empty()) return false;
  errno = 0;
  char* end = nullptr;
  v = std::strtoll(t.c_str(), &end, 10);
  return errno == 0 && end && *end == '\0';
}

bool parse_double(const std::string& s, double& v) {
  const std::string t = trim(s);
  if (t.empty()) return false;
  errno = 0;
  char* end = nullptr;
  v = std::strtod(t.c_str(), &end);
  return end && *end == '\0' && errno != ERANGE;
}

// Whitespace-separated tokens.
std::vector<std::string> tokens(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  std::string t;
  while (in >> t) out.push_back(t);
  return out;
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == sep) {
      out.push_back(trim(cur));
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(trim(cur));
  return out;
}

bool is_dir(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

// Load and parse an XML file; the root must be NEKTAR.
const tinyxml2::XMLElement* load_xml(tinyxml2::XMLDocument& doc, const std::string& path, const std::string& where) {
  if (is_dir(path))
    throw IoError(where + ": " + quote(path) +
                  " is a folder (a parallel Nektar++ output); expected one XML file (FieldConvert can merge it)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(where + ": " + quote(path) + ": cannot open: " + std::strerror(errno));
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw IoError(where + ": " + quote(path) + ": read error");
  if (bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0x1f && static_cast<unsigned char>(bytes[1]) == 0x8b)
    throw InputError(where + ": " + quote(path) + ": gzip-compressed; expected a plain Nektar++ XML file");
  if (bytes.size() >= 8 && bytes.compare(1, 3, "HDF") == 0)
    throw InputError(where + ": " + quote(path) + ": an HDF5 file; only the XML format of Nektar++ is supported");
  const tinyxml2::XMLError rc = doc.Parse(bytes.data(), bytes.size());
  if (rc != tinyxml2::XML_SUCCESS) {
    const char* msg = doc.ErrorStr();
    throw InputError(where + ": " + quote(path) + ": malformed XML: " + (msg ? msg : "parse error"));
  }
  const tinyxml2::XMLElement* root = doc.FirstChildElement("NEKTAR");
  if (!root) throw InputError(where + ": " + quote(path) + ": no NEKTAR root element; expected a Nektar++ XML file");
  return root;
}

// Decode a COMPRESSED section into records of `ncols` little-endian 8-byte words.
template <class T>
std::vector<T> decode_records(const tinyxml2::XMLElement* e, const std::string& what, std::size_t words) {
  const char* c = e->Attribute("COMPRESSED");
  if (!c || std::string(c) != kCompressString)
    throw InputError(what + ": COMPRESSED=" + quote(c ? c : "") + "; expected " + quote(kCompressString));
  if (const char* bits = e->Attribute("BITSIZE"))
    if (std::string(bits) != "64") throw InputError(what + ": BITSIZE=" + quote(bits) + "; expected \"64\"");
  const std::vector<unsigned char> bytes = nektar_b64z_decode(element_text(e), what);
  const std::size_t rec = 8 * words;
  if (bytes.size() % rec != 0)
    throw InputError(what + ": " + int_str(bytes.size()) + " decompressed bytes is not a whole number of " +
                     int_str(rec) + "-byte records");
  std::vector<T> out(bytes.size() / rec);
  static_assert(sizeof(T) % 8 == 0, "records are 8-byte words");
  if (!out.empty()) std::memcpy(out.data(), bytes.data(), bytes.size());
  return out;
}

struct VertexRec {
  std::int64_t id;
  double x, y, z;
};
struct EdgeRec {
  std::int64_t id, v0, v1;
};
struct TriRec {
  std::int64_t id, e[3];
};
struct QuadRec {
  std::int64_t id, e[4];
};
struct TetRec {
  std::int64_t id, f[4];
};
struct HexRec {
  std::int64_t id, f[6];
};
struct CurveInfoRec {
  std::int64_t id, entity, npoints, ptid, ptoffset, ptype;
};
struct IndexRec {
  std::int64_t i;
};

static_assert(sizeof(VertexRec) == 32 && sizeof(EdgeRec) == 24 && sizeof(TriRec) == 32 && sizeof(QuadRec) == 40 &&
                  sizeof(TetRec) == 40 && sizeof(HexRec) == 56 && sizeof(CurveInfoRec) == 48,
              "Nektar++'s MeshEntities are packed 8-byte words");

int checked_id(std::int64_t v, const std::string& what, const char* kind) {
  if (v < 0 || v > std::numeric_limits<int>::max())
    throw InputError(what + ": " + kind + " id " + std::to_string(v) + " out of range; expected 0.." +
                     int_str(std::numeric_limits<int>::max()));
  return static_cast<int>(v);
}

int id_attribute(const tinyxml2::XMLElement* e, const std::string& what, const char* name = "ID") {
  const char* a = e->Attribute(name);
  long long v = 0;
  if (!a) throw InputError(what + ": <" + e->Name() + "> without " + name + "; expected " + name + "=\"<integer>\"");
  if (!parse_int(a, v)) throw InputError(what + ": <" + e->Name() + " " + name + "=" + quote(a) + ">: not an integer");
  return checked_id(v, what, e->Name());
}

// Integer list in an element body ("0 1 2").
std::vector<int> int_list(const tinyxml2::XMLElement* e, const std::string& what, std::size_t n) {
  const auto t = tokens(element_text(e));
  if (t.size() != n)
    throw InputError(what + ": <" + e->Name() + " ID=" + quote(e->Attribute("ID") ? e->Attribute("ID") : "") +
                     "> has " + int_str(t.size()) + " entries; expected " + int_str(n));
  std::vector<int> out;
  for (const auto& s : t) {
    long long v = 0;
    if (!parse_int(s, v)) throw InputError(what + ": <" + e->Name() + "> entry " + quote(s) + " is not an integer");
    out.push_back(checked_id(v, what, "referenced"));
  }
  return out;
}

double scale_attr(const tinyxml2::XMLElement* e, const char* name, double dflt, const std::string& what) {
  const char* a = e->Attribute(name);
  if (!a) return dflt;
  double v = 0;
  if (!parse_double(a, v) || !std::isfinite(v))
    throw InputError(what + ": VERTEX " + name + "=" + quote(a) +
                     " is not a plain number (expressions are not supported)");
  return v;
}

// ---- element setup as Nektar++ does it ----------------------------------------

struct Builder {
  const NektarMesh& m;
  const std::string& what;

  const std::array<int, 4>& face(int fid) const {
    auto it = m.faces.find(fid);
    if (it == m.faces.end()) throw InputError(what + ": element refers to face " + int_str(fid) + ", which is not in FACE");
    return it->second;
  }
  const std::array<int, 2>& edge(int eid) const {
    auto it = m.edges.find(eid);
    if (it == m.edges.end()) throw InputError(what + ": a face refers to edge " + int_str(eid) + ", which is not in EDGE");
    return it->second;
  }
  static int nedges_of(const std::array<int, 4>& f) { return f[3] < 0 ? 3 : 4; }

  // The one edge shared by faces a and b (Nektar++'s "connected faces share exactly one edge").
  int shared_edge(int fa, int fb, const std::string& elem) const {
    const auto& A = face(fa);
    const auto& B = face(fb);
    int found = -1, count = 0;
    for (int i = 0; i < nedges_of(A); ++i)
      for (int j = 0; j < nedges_of(B); ++j)
        if (A[i] == B[j]) {
          found = A[i];
          ++count;
        }
    if (count != 1)
      throw InputError(what + ": " + elem + ": faces " + int_str(fa) + " and " + int_str(fb) + " share " +
                       int_str(count) + " edges; expected exactly 1");
    return found;
  }
  // Edge i of face fa that equals edge `e0` (must be present).
  void require_in(int eid, int fid, const std::string& elem) const {
    const auto& F = face(fid);
    for (int i = 0; i < nedges_of(F); ++i)
      if (F[i] == eid) return;
    throw InputError(what + ": " + elem + ": edge " + int_str(eid) + " is not on face " + int_str(fid) +
                     "; the faces do not close an element");
  }
  // First two vertices from edges e0, e1 (Nektar++: the shared vertex second).
  void first_two(int e0, int e1, int& v0, int& v1, const std::string& elem) const {
    const auto& E0 = edge(e0);
    const auto& E1 = edge(e1);
    if (E0[0] == E1[0] || E0[0] == E1[1]) {
      v0 = E0[1];
      v1 = E0[0];
    } else if (E0[1] == E1[0] || E0[1] == E1[1]) {
      v0 = E0[0];
      v1 = E0[1];
    } else {
      throw InputError(what + ": " + elem + ": edges " + int_str(e0) + " and " + int_str(e1) +
                       " do not share a vertex");
    }
  }
  int other_end(int eid, int v, const std::string& elem) const {
    const auto& E = edge(eid);
    if (E[0] == v) return E[1];
    if (E[1] == v) return E[0];
    throw InputError(what + ": " + elem + ": edge " + int_str(eid) + " does not touch vertex " + int_str(v));
  }

  NektarElement tet(int id, const std::array<int, 4>& f) const {
    const std::string elem = "tetrahedron A " + int_str(id);
    for (int i = 0; i < 4; ++i)
      if (nedges_of(face(f[i])) != 3)
        throw InputError(what + ": " + elem + ": face " + int_str(f[i]) + " is a quadrilateral; expected triangles");
    NektarElement e;
    e.id = id;
    e.shape = NektarShape::Tetrahedron;
    e.nverts = 4;
    e.nfaces = 4;
    for (int i = 0; i < 4; ++i) e.faces[i] = f[i];
    e.edges.fill(-1);
    // Bottom edges: the first edge of faces 1..3, each on face 0.
    if (face(f[0])[0] != face(f[1])[0])
      throw InputError(what + ": " + elem + ": the first edge of face " + int_str(f[0]) + " (" +
                       int_str(face(f[0])[0]) + ") differs from the first edge of face " + int_str(f[1]) + " (" +
                       int_str(face(f[1])[0]) + "); expected Nektar++'s tetrahedron face order");
    for (int k = 1; k < 4; ++k) {
      e.edges[k - 1] = face(f[k])[0];
      require_in(e.edges[k - 1], f[0], elem);
    }
    e.edges[3] = shared_edge(f[1], f[3], elem);
    e.edges[4] = shared_edge(f[1], f[2], elem);
    e.edges[5] = shared_edge(f[2], f[3], elem);
    int v0 = 0, v1 = 0;
    first_two(e.edges[0], e.edges[1], v0, v1, elem);
    const int v2 = other_end(e.edges[1], v1, elem);
    const auto& E3 = edge(e.edges[3]);
    int v3;
    if (E3[0] == v0)
      v3 = E3[1];
    else if (E3[1] == v0)
      v3 = E3[0];
    else
      throw InputError(what + ": " + elem + ": edge " + int_str(e.edges[3]) + " does not touch vertex " + int_str(v0));
    auto joins = [&](int eid, int a, int b) {
      const auto& E = edge(eid);
      return (E[0] == a && E[1] == b) || (E[0] == b && E[1] == a);
    };
    if (!joins(e.edges[2], v0, v2) || !joins(e.edges[4], v1, v3) || !joins(e.edges[5], v2, v3))
      throw InputError(what + ": " + elem + ": its edges do not form a tetrahedron");
    e.verts = {v0, v1, v2, v3, -1, -1, -1, -1};
    check_distinct(e, elem);
    return e;
  }

  NektarElement hex(int id, const std::array<int, 6>& f) const {
    const std::string elem = "hexahedron H " + int_str(id);
    for (int i = 0; i < 6; ++i)
      if (nedges_of(face(f[i])) != 4)
        throw InputError(what + ": " + elem + ": face " + int_str(f[i]) + " is a triangle; expected quadrilaterals");
    NektarElement e;
    e.id = id;
    e.shape = NektarShape::Hexahedron;
    e.nverts = 8;
    e.nfaces = 6;
    for (int i = 0; i < 6; ++i) e.faces[i] = f[i];
    for (int k = 1; k < 5; ++k) e.edges[k - 1] = shared_edge(f[0], f[k], elem);
    e.edges[4] = shared_edge(f[1], f[4], elem);
    for (int k = 1; k < 4; ++k) e.edges[4 + k] = shared_edge(f[k], f[k + 1], elem);
    for (int k = 1; k < 5; ++k) e.edges[7 + k] = shared_edge(f[5], f[k], elem);
    int v[8];
    first_two(e.edges[0], e.edges[1], v[0], v[1], elem);
    v[2] = other_end(e.edges[1], v[1], elem);
    v[3] = other_end(e.edges[2], v[2], elem);
    first_two(e.edges[8], e.edges[9], v[4], v[5], elem);
    v[6] = other_end(e.edges[9], v[5], elem);
    v[7] = other_end(e.edges[10], v[6], elem);
    for (int i = 0; i < 8; ++i) e.verts[i] = v[i];
    check_distinct(e, elem);
    // The faces must be the reference faces of these vertices (Nektar++'s
    // orientation set-up relies on it).
    static const int fv[6][4] = {{0, 1, 2, 3}, {0, 1, 5, 4}, {1, 2, 6, 5}, {3, 2, 6, 7}, {0, 3, 7, 4}, {4, 5, 6, 7}};
    for (int k = 0; k < 6; ++k) {
      std::set<int> want, got;
      for (int j = 0; j < 4; ++j) want.insert(v[fv[k][j]]);
      const auto& F = face(f[k]);
      for (int j = 0; j < 4; ++j) {
        got.insert(edge(F[j])[0]);
        got.insert(edge(F[j])[1]);
      }
      if (want != got)
        throw InputError(what + ": " + elem + ": face " + int_str(f[k]) + " is not local face " + int_str(k) +
                         " of the vertices its edges define; the faces do not close a hexahedron");
    }
    return e;
  }

  void check_distinct(const NektarElement& e, const std::string& elem) const {
    std::set<int> s(e.verts.begin(), e.verts.begin() + e.nverts);
    if (static_cast<int>(s.size()) != e.nverts)
      throw InputError(what + ": " + elem + ": " + int_str(s.size()) + " distinct vertices; expected " +
                       int_str(e.nverts));
    for (int i = 0; i < e.nverts; ++i)
      if (!m.vertex_index.count(e.verts[i]))
        throw InputError(what + ": " + elem + ": edge refers to vertex " + int_str(e.verts[i]) +
                         ", which is not in VERTEX");
  }
};

void add_vertex(NektarMesh& m, int id, Vec3 p, const std::string& what) {
  if (!is_finite(p)) throw InputError(what + ": vertex " + int_str(id) + " has a non-finite coordinate");
  if (!m.vertex_index.emplace(id, static_cast<int>(m.vertices.size())).second)
    throw InputError(what + ": vertex " + int_str(id) + " is defined twice");
  m.vertices.push_back(p);
}

void add_edge(NektarMesh& m, int id, int a, int b, const std::string& what) {
  if (a == b) throw InputError(what + ": edge " + int_str(id) + " joins vertex " + int_str(a) + " to itself");
  for (int v : {a, b})
    if (!m.vertex_index.count(v))
      throw InputError(what + ": edge " + int_str(id) + " refers to vertex " + int_str(v) + ", which is not in VERTEX");
  if (!m.edges.emplace(id, std::array<int, 2>{a, b}).second)
    throw InputError(what + ": edge " + int_str(id) + " is defined twice");
}

void add_face(NektarMesh& m, int id, const std::array<int, 4>& e, const std::string& what) {
  const int n = e[3] < 0 ? 3 : 4;
  for (int i = 0; i < n; ++i)
    if (!m.edges.count(e[i]))
      throw InputError(what + ": face " + int_str(id) + " refers to edge " + int_str(e[i]) + ", which is not in EDGE");
  if (!m.faces.emplace(id, e).second) throw InputError(what + ": face " + int_str(id) + " is defined twice");
}

void add_element(NektarMesh& m, NektarElement e, const std::string& what) {
  if (!m.element_index.emplace(e.id, static_cast<int>(m.elements.size())).second)
    throw InputError(what + ": element " + int_str(e.id) + " is defined twice");
  m.elements.push_back(e);
}

const tinyxml2::XMLElement* section(const tinyxml2::XMLElement* geom, const char* name, const std::string& what) {
  const tinyxml2::XMLElement* s = geom->FirstChildElement(name);
  if (!s) throw InputError(what + ": no " + name + " section in GEOMETRY");
  return s;
}

void read_curves(NektarMesh& m, const tinyxml2::XMLElement* curved, const std::string& what, double sc[3],
                 double mv[3]) {
  auto place = [&](Vec3 p) { return Vec3{p.x * sc[0] + mv[0], p.y * sc[1] + mv[1], p.z * sc[2] + mv[2]}; };
  if (curved->Attribute("COMPRESSED")) {
    const std::string w = what + ": CURVED";
    std::vector<CurveInfoRec> einfo, finfo;
    std::vector<IndexRec> index;
    std::vector<VertexRec> pts;
    bool have_pts = false;
    for (const auto* x = curved->FirstChildElement(); x; x = x->NextSiblingElement()) {
      const std::string tag = x->Name();
      if (tag == "E") {
        auto v = decode_records<CurveInfoRec>(x, w + "/E", 6);
        einfo.insert(einfo.end(), v.begin(), v.end());
      } else if (tag == "F") {
        auto v = decode_records<CurveInfoRec>(x, w + "/F", 6);
        finfo.insert(finfo.end(), v.begin(), v.end());
      } else if (tag == "DATAPOINTS") {
        const auto* idx = x->FirstChildElement("INDEX");
        const auto* p = x->FirstChildElement("POINTS");
        if (!idx || !p) throw InputError(w + "/DATAPOINTS: expected INDEX and POINTS children");
        // INDEX and POINTS carry no COMPRESSED attribute of their own.
        const auto ib = nektar_b64z_decode(element_text(idx), w + "/DATAPOINTS/INDEX");
        const auto pb = nektar_b64z_decode(element_text(p), w + "/DATAPOINTS/POINTS");
        if (ib.size() % 8 || pb.size() % 32)
          throw InputError(w + "/DATAPOINTS: decompressed sizes " + int_str(ib.size()) + " and " + int_str(pb.size()) +
                           " are not whole numbers of 8- and 32-byte records");
        index.resize(ib.size() / 8);
        pts.resize(pb.size() / 32);
        if (!index.empty()) std::memcpy(index.data(), ib.data(), ib.size());
        if (!pts.empty()) std::memcpy(pts.data(), pb.data(), pb.size());
        have_pts = true;
      } else {
        throw InputError(w + ": unknown element <" + tag + ">; expected E, F or DATAPOINTS");
      }
    }
    auto build = [&](const std::vector<CurveInfoRec>& info, std::vector<NektarCurve>& out, const char* kind) {
      for (const auto& r : info) {
        if (!have_pts) throw InputError(w + ": curved " + kind + "s but no DATAPOINTS");
        NektarCurve c;
        c.id = checked_id(r.id, w, "curve");
        c.entity = checked_id(r.entity, w, kind);
        c.type = "points type " + std::to_string(r.ptype);
        if (r.npoints < 0 || r.ptoffset < 0 || r.npoints > static_cast<std::int64_t>(index.size()) ||
            r.ptoffset > static_cast<std::int64_t>(index.size()) - r.npoints)
          throw InputError(w + ": curve " + int_str(c.id) + " points " + std::to_string(r.ptoffset) + "+" +
                           std::to_string(r.npoints) + " outside the INDEX of " + int_str(index.size()));
        for (std::int64_t j = 0; j < r.npoints; ++j) {
          const std::int64_t k = index[r.ptoffset + j].i;
          if (k < 0 || k >= static_cast<std::int64_t>(pts.size()))
            throw InputError(w + ": curve " + int_str(c.id) + " point index " + std::to_string(k) + " outside POINTS (" +
                             int_str(pts.size()) + ")");
          const Vec3 p = place({pts[k].x, pts[k].y, pts[k].z});
          if (!is_finite(p)) throw InputError(w + ": curve " + int_str(c.id) + " has a non-finite point");
          c.points.push_back(p);
        }
        out.push_back(std::move(c));
      }
    };
    build(einfo, m.curved_edges, "edge");
    build(finfo, m.curved_faces, "face");
    return;
  }
  for (const auto* x = curved->FirstChildElement(); x; x = x->NextSiblingElement()) {
    const std::string tag = x->Name();
    if (tag != "E" && tag != "F") throw InputError(what + ": CURVED: unknown element <" + tag + ">; expected E or F");
    const std::string w = what + ": CURVED/" + tag;
    NektarCurve c;
    c.id = id_attribute(x, w);
    c.entity = id_attribute(x, w, tag == "E" ? "EDGEID" : "FACEID");
    const char* type = x->Attribute("TYPE");
    if (!type) throw InputError(w + " " + int_str(c.id) + ": no TYPE attribute");
    c.type = type;
    const int np = id_attribute(x, w, "NUMPOINTS");
    const auto t = tokens(element_text(x));
    if (t.size() != static_cast<std::size_t>(3) * np)
      throw InputError(w + " " + int_str(c.id) + ": " + int_str(t.size()) + " numbers; expected 3 x NUMPOINTS = " +
                       int_str(3LL * np));
    for (std::size_t i = 0; i < t.size(); i += 3) {
      Vec3 p;
      for (int k = 0; k < 3; ++k)
        if (!parse_double(t[i + k], p[k]) || !std::isfinite(p[k]))
          throw InputError(w + " " + int_str(c.id) + ": " + quote(t[i + k]) + " is not a finite number");
      c.points.push_back(place(p));
    }
    (tag == "E" ? m.curved_edges : m.curved_faces).push_back(std::move(c));
  }
}

}  // namespace

const char* nektar_shape_name(NektarShape s) {
  return s == NektarShape::Tetrahedron ? "Tetrahedron" : "Hexahedron";
}

std::string nektar_b64z_encode(const void* data, std::size_t n) {
  std::vector<unsigned char> z = deflate_buffer(data, n, false, 9);
  while (z.size() % 3) z.push_back(0);
  static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve(z.size() / 3 * 4);
  for (std::size_t i = 0; i < z.size(); i += 3) {
    const unsigned v = (unsigned(z[i]) << 16) | (unsigned(z[i + 1]) << 8) | unsigned(z[i + 2]);
    out += abc[(v >> 18) & 63];
    out += abc[(v >> 12) & 63];
    out += abc[(v >> 6) & 63];
    out += abc[v & 63];
  }
  return out;
}

std::vector<unsigned char> nektar_b64z_decode(const std::string& text, const std::string& what) {
  std::vector<unsigned char> bin;
  bin.reserve(text.size() / 4 * 3 + 3);
  unsigned acc = 0;
  int nbits = 0;
  std::size_t nchars = 0;
  bool padding = false;
  for (unsigned char c : text) {
    if (is_space(static_cast<char>(c))) continue;
    if (c == '=') {
      padding = true;
      continue;
    }
    const int v = b64_value(c);
    if (v < 0 || padding)
      throw InputError(what + ": bad base64 character " + (v < 0 ? quote(std::string(1, static_cast<char>(c))) : "after '='") +
                       " at offset " + int_str(nchars) + "; expected B64Z-LittleEndian data");
    ++nchars;
    acc = (acc << 6) | static_cast<unsigned>(v);
    nbits += 6;
    if (nbits >= 8) {
      nbits -= 8;
      bin.push_back(static_cast<unsigned char>((acc >> nbits) & 0xff));
    }
  }
  if (nchars == 0) throw InputError(what + ": empty compressed data; expected B64Z-LittleEndian base64 text");
  if (nchars % 4 == 1) throw InputError(what + ": truncated base64 data (" + int_str(nchars) + " characters)");
  // zlib inflate into a growing buffer.
  z_stream zs;
  std::memset(&zs, 0, sizeof zs);
  if (inflateInit(&zs) != Z_OK) throw InputError(what + ": cannot initialise zlib");
  const InflateGuard guard{&zs};
  std::vector<unsigned char> out(std::max<std::size_t>(1024, bin.size() * 4));
  zs.next_in = bin.data();
  zs.avail_in = static_cast<uInt>(bin.size());
  std::size_t done = 0;
  for (;;) {
    if (done == out.size()) {
      if (out.size() >= kMaxInflated)
        throw InputError(what + ": compressed data expands beyond " + int_str(kMaxInflated) + " bytes");
      out.resize(std::min(kMaxInflated, out.size() * 2));
    }
    zs.next_out = out.data() + done;
    zs.avail_out = static_cast<uInt>(out.size() - done);
    const int rc = inflate(&zs, Z_NO_FLUSH);
    done = out.size() - zs.avail_out;
    if (rc == Z_STREAM_END) break;
    if (rc == Z_OK) continue;
    if (rc == Z_BUF_ERROR && zs.avail_out > 0)
      throw InputError(what + ": truncated zlib data (the stream ends early after " + int_str(done) + " bytes)");
    if (rc == Z_BUF_ERROR) continue;
    throw InputError(what + ": corrupt zlib data (" + (zs.msg ? zs.msg : ("zlib error " + int_str(rc))) + ")");
  }
  // Nektar++ pads the binary to a multiple of 3 with zero bytes: only zeros may follow the stream.
  for (uInt i = 0; i < zs.avail_in; ++i)
    if (zs.next_in[i] != 0)
      throw InputError(what + ": " + int_str(zs.avail_in) + " bytes of trailing data after the zlib stream");
  out.resize(done);
  return out;
}

bool NektarMesh::element_curved(const NektarElement& e, std::string* what) const {
  const int ne = e.shape == NektarShape::Tetrahedron ? 6 : 12;
  for (const auto& c : curved_edges)
    for (int i = 0; i < ne; ++i)
      if (e.edges[i] == c.entity) {
        if (what) *what = "edge " + int_str(c.entity);
        return true;
      }
  for (const auto& c : curved_faces)
    for (int i = 0; i < e.nfaces; ++i)
      if (e.faces[i] == c.entity) {
        if (what) *what = "face " + int_str(c.entity);
        return true;
      }
  return false;
}

NektarMesh read_nektar_mesh(const std::string& path) {
  tinyxml2::XMLDocument doc;
  const auto* root = load_xml(doc, path, "read_nektar_mesh");
  const std::string what = "read_nektar_mesh: " + quote(path);
  NektarMesh m;
  m.path = path;
  const auto* geom = root->FirstChildElement("GEOMETRY");
  if (!geom) throw InputError(what + ": no GEOMETRY section; expected a Nektar++ mesh or session file");
  if (const char* d = geom->Attribute("DIM")) {
    long long v = 0;
    if (!parse_int(d, v) || v != 3) throw InputError(what + ": GEOMETRY DIM=" + quote(d) + "; expected \"3\"");
  }
  if (const char* d = geom->Attribute("SPACE")) {
    long long v = 0;
    if (!parse_int(d, v) || v != 3) throw InputError(what + ": GEOMETRY SPACE=" + quote(d) + "; expected \"3\"");
  }
  if (geom->Attribute("PARTITION"))
    throw InputError(what + ": a partitioned mesh (GEOMETRY PARTITION); expected the whole mesh");

  // VERTEX
  const auto* vx = section(geom, "VERTEX", what);
  double sc[3] = {scale_attr(vx, "XSCALE", 1, what), scale_attr(vx, "YSCALE", 1, what), scale_attr(vx, "ZSCALE", 1, what)};
  double mv[3] = {scale_attr(vx, "XMOVE", 0, what), scale_attr(vx, "YMOVE", 0, what), scale_attr(vx, "ZMOVE", 0, what)};
  auto place = [&](double x, double y, double z) { return Vec3{x * sc[0] + mv[0], y * sc[1] + mv[1], z * sc[2] + mv[2]}; };
  if (vx->Attribute("COMPRESSED")) {
    for (const auto& r : decode_records<VertexRec>(vx, what + ": VERTEX", 4))
      add_vertex(m, checked_id(r.id, what, "vertex"), place(r.x, r.y, r.z), what);
  } else {
    for (const auto* v = vx->FirstChildElement(); v; v = v->NextSiblingElement()) {
      if (std::string(v->Name()) != "V") throw InputError(what + ": VERTEX: unknown element <" + v->Name() + ">; expected V");
      const int id = id_attribute(v, what + ": VERTEX");
      const auto t = tokens(element_text(v));
      if (t.size() != 3)
        throw InputError(what + ": vertex " + int_str(id) + " has " + int_str(t.size()) + " coordinates; expected 3");
      double c[3];
      for (int k = 0; k < 3; ++k)
        if (!parse_double(t[k], c[k]))
          throw InputError(what + ": vertex " + int_str(id) + " coordinate " + quote(t[k]) + " is not a number");
      add_vertex(m, id, place(c[0], c[1], c[2]), what);
    }
  }
  if (m.vertices.empty()) throw InputError(what + ": VERTEX section is empty");

  // EDGE
  const auto* ex = section(geom, "EDGE", what);
  if (ex->Attribute("COMPRESSED")) {
    for (const auto& r : decode_records<EdgeRec>(ex, what + ": EDGE", 3))
      add_edge(m, checked_id(r.id, what, "edge"), checked_id(r.v0, what, "vertex"), checked_id(r.v1, what, "vertex"), what);
  } else {
    for (const auto* e = ex->FirstChildElement(); e; e = e->NextSiblingElement()) {
      if (std::string(e->Name()) != "E") throw InputError(what + ": EDGE: unknown element <" + e->Name() + ">; expected E");
      const int id = id_attribute(e, what + ": EDGE");
      const auto v = int_list(e, what + ": EDGE", 2);
      add_edge(m, id, v[0], v[1], what);
    }
  }

  // FACE
  const auto* fx = section(geom, "FACE", what);
  for (const auto* f = fx->FirstChildElement(); f; f = f->NextSiblingElement()) {
    const std::string tag = f->Name();
    if (tag != "T" && tag != "Q")
      throw InputError(what + ": FACE: unknown face type <" + tag + ">; expected T (triangle) or Q (quadrilateral)");
    const bool tri = tag == "T";
    if (f->Attribute("COMPRESSED")) {
      if (tri) {
        for (const auto& r : decode_records<TriRec>(f, what + ": FACE/T", 4))
          add_face(m, checked_id(r.id, what, "face"),
                   {checked_id(r.e[0], what, "edge"), checked_id(r.e[1], what, "edge"), checked_id(r.e[2], what, "edge"), -1},
                   what);
      } else {
        for (const auto& r : decode_records<QuadRec>(f, what + ": FACE/Q", 5))
          add_face(m, checked_id(r.id, what, "face"),
                   {checked_id(r.e[0], what, "edge"), checked_id(r.e[1], what, "edge"), checked_id(r.e[2], what, "edge"),
                    checked_id(r.e[3], what, "edge")},
                   what);
      }
    } else {
      const int id = id_attribute(f, what + ": FACE");
      const auto e = int_list(f, what + ": FACE", tri ? 3 : 4);
      add_face(m, id, {e[0], e[1], e[2], tri ? -1 : e[3]}, what);
    }
  }

  // ELEMENT
  const auto* elx = section(geom, "ELEMENT", what);
  const Builder b{m, what};
  for (const auto* el = elx->FirstChildElement(); el; el = el->NextSiblingElement()) {
    const std::string tag = el->Name();
    if (tag == "R" || tag == "P")
      throw InputError(what + ": " + (tag == "R" ? "prism" : "pyramid") + " elements (" + tag +
                       ") are not supported yet; expected tetrahedra (A) and hexahedra (H)");
    if (tag == "S" || tag == "T" || tag == "Q")
      throw InputError(what + ": ELEMENT <" + tag + ">: a 1D or 2D element; expected a 3D mesh (A, H)");
    if (tag != "A" && tag != "H")
      throw InputError(what + ": ELEMENT: unknown element type <" + tag + ">; expected A (tetrahedron) or H (hexahedron)");
    const bool tet = tag == "A";
    if (el->Attribute("COMPRESSED")) {
      if (tet) {
        for (const auto& r : decode_records<TetRec>(el, what + ": ELEMENT/A", 5)) {
          std::array<int, 4> f;
          for (int k = 0; k < 4; ++k) f[k] = checked_id(r.f[k], what, "face");
          add_element(m, b.tet(checked_id(r.id, what, "element"), f), what);
        }
      } else {
        for (const auto& r : decode_records<HexRec>(el, what + ": ELEMENT/H", 7)) {
          std::array<int, 6> f;
          for (int k = 0; k < 6; ++k) f[k] = checked_id(r.f[k], what, "face");
          add_element(m, b.hex(checked_id(r.id, what, "element"), f), what);
        }
      }
    } else {
      const int id = id_attribute(el, what + ": ELEMENT");
      const auto f = int_list(el, what + ": ELEMENT", tet ? 4 : 6);
      if (tet)
        add_element(m, b.tet(id, {f[0], f[1], f[2], f[3]}), what);
      else
        add_element(m, b.hex(id, {f[0], f[1], f[2], f[3], f[4], f[5]}), what);
    }
  }
  if (m.elements.empty()) throw InputError(what + ": ELEMENT section has no elements");

  if (const auto* cx = geom->FirstChildElement("CURVED")) read_curves(m, cx, what, sc, mv);

  if (const auto* exps = root->FirstChildElement("EXPANSIONS")) {
    if (const auto* e = exps->FirstChildElement("E")) {
      if (const char* nm = e->Attribute("NUMMODES")) {
        long long v = 0;
        if (parse_int(nm, v) && v > 0 && v <= kMaxModes) m.expansion_modes = static_cast<int>(v);
      }
      if (const char* t = e->Attribute("TYPE")) m.expansion_type = t;
      if (const char* f = e->Attribute("FIELDS")) m.expansion_fields = f;
    }
  }
  return m;
}

int nektar_num_coeffs(NektarShape s, const std::array<int, 3>& n) {
  if (s == NektarShape::Hexahedron) return n[0] * n[1] * n[2];
  int c = 0;
  for (int p = 0; p < n[0]; ++p)
    for (int q = 0; q < n[1] - p; ++q) c += std::max(0, n[2] - p - q);
  return c;
}

int NektarField::variable(const std::string& name) const {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return static_cast<int>(i);
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
  throw UsageError("field " + quote(path) + " has no variable " + quote(name) + "; it has " + list);
}

namespace {

// "0-3,7,9-12" -> ids.
std::vector<int> parse_ids(const std::string& s, const std::string& what, std::size_t max_ids) {
  std::vector<int> out;
  for (const auto& part : split(s, ',')) {
    if (part.empty()) throw InputError(what + ": ID=" + quote(s) + " has an empty entry; expected e.g. \"0-3,7\"");
    const auto dash = part.find('-');
    long long a = 0, b = 0;
    if (dash == std::string::npos) {
      if (!parse_int(part, a)) throw InputError(what + ": ID entry " + quote(part) + " is not an integer");
      b = a;
    } else if (!parse_int(part.substr(0, dash), a) || !parse_int(part.substr(dash + 1), b)) {
      throw InputError(what + ": ID range " + quote(part) + " is not \"<first>-<last>\"");
    }
    if (a < 0 || b < a || b > std::numeric_limits<int>::max())
      throw InputError(what + ": ID range " + quote(part) + " is empty or out of range");
    if (static_cast<unsigned long long>(b - a) >= max_ids || out.size() + static_cast<std::size_t>(b - a) >= max_ids)
      throw InputError(what + ": ID lists more than " + int_str(max_ids) +
                       " elements, more than its data can hold (at least 4 coefficients per element and field)");
    for (long long i = a; i <= b; ++i) out.push_back(static_cast<int>(i));
  }
  return out;
}

}  // namespace

NektarField read_nektar_field(const std::string& path) {
  tinyxml2::XMLDocument doc;
  const auto* root = load_xml(doc, path, "read_nektar_field");
  const std::string what = "read_nektar_field: " + quote(path);
  NektarField fld;
  fld.path = path;
  int block = 0;
  for (const auto* nek = root; nek; nek = nek->NextSiblingElement("NEKTAR")) {
    for (const auto* e = nek->FirstChildElement("ELEMENTS"); e; e = e->NextSiblingElement("ELEMENTS"), ++block) {
      const std::string w = what + ": ELEMENTS block " + int_str(block);
      auto attr = [&](const char* name) -> std::string {
        const char* a = e->Attribute(name);
        if (!a) throw InputError(w + ": no " + name + " attribute");
        return a;
      };
      for (const char* unsupported : {"HOMOGENEOUSLENGTHS", "POINTSTYPE", "NUMPOINTSPERDIR"})
        if (e->Attribute(unsupported))
          throw InputError(w + ": attribute " + unsupported + " (homogeneous or nodal expansions) is not supported");
      if (const char* c = e->Attribute("COMPRESSED"))
        if (std::string(c) != kCompressString)
          throw InputError(w + ": COMPRESSED=" + quote(c) + "; expected " + quote(kCompressString));
      if (const char* bits = e->Attribute("BITSIZE"))
        if (std::string(bits) != "64") throw InputError(w + ": BITSIZE=" + quote(bits) + "; expected \"64\"");
      // FIELDS
      std::vector<std::string> names = split(attr("FIELDS"), ',');
      for (const auto& n : names)
        if (n.empty()) throw InputError(w + ": FIELDS=" + quote(attr("FIELDS")) + " has an empty name");
      if (fld.names.empty()) {
        fld.names = names;
      } else if (names != fld.names) {
        throw InputError(w + ": FIELDS=" + quote(attr("FIELDS")) + " differs from the first block's; expected the same variables in every block");
      }
      // SHAPE + BASIS
      const std::string shape = attr("SHAPE");
      NektarShape s;
      std::vector<std::string> want;
      if (shape == "Tetrahedron") {
        s = NektarShape::Tetrahedron;
        want = {"Modified_A", "Modified_B", "Modified_C"};
      } else if (shape == "Hexahedron") {
        s = NektarShape::Hexahedron;
        want = {"Modified_A", "Modified_A", "Modified_A"};
      } else {
        throw InputError(w + ": SHAPE=" + quote(shape) + " is not supported; expected \"Tetrahedron\" or \"Hexahedron\"");
      }
      const std::string basis = attr("BASIS");
      if (split(basis, ',') != want) {
        std::string exp;
        for (const auto& x : want) exp += (exp.empty() ? "" : ",") + x;
        throw InputError(w + ": BASIS=" + quote(basis) + " for a " + shape + " is not supported; expected " + quote(exp));
      }
      // data, then IDs (bounded by what the data can hold)
      const std::string id_text = attr("ID");
      const std::vector<unsigned char> bytes = nektar_b64z_decode(element_text(e), w + ": data");
      const std::vector<int> ids = parse_ids(id_text, w, bytes.size() / (8 * 4 * names.size()) + 1);
      // NUMMODESPERDIR
      const std::string nm = attr("NUMMODESPERDIR");
      bool uni;
      if (nm.rfind("UNIORDER:", 0) == 0)
        uni = true;
      else if (nm.rfind("MIXORDER:", 0) == 0)
        uni = false;
      else
        throw InputError(w + ": NUMMODESPERDIR=" + quote(nm) + "; expected \"UNIORDER:P,Q,R\" or \"MIXORDER:...\"");
      std::vector<int> modes;
      for (const auto& t : split(nm.substr(9), ',')) {
        long long v = 0;
        if (!parse_int(t, v) || v < 2 || v > kMaxModes)
          throw InputError(w + ": NUMMODESPERDIR entry " + quote(t) + "; expected an integer in 2.." + int_str(kMaxModes));
        modes.push_back(static_cast<int>(v));
      }
      const std::size_t need = uni ? 3 : 3 * ids.size();
      if (modes.size() != need)
        throw InputError(w + ": NUMMODESPERDIR has " + int_str(modes.size()) + " numbers; expected " + int_str(need) +
                         (uni ? "" : " (3 per element)"));
      std::size_t per_field = 0;
      std::vector<std::array<int, 3>> em(ids.size());
      for (std::size_t k = 0; k < ids.size(); ++k) {
        const std::size_t o = uni ? 0 : 3 * k;
        em[k] = {modes[o], modes[o + 1], modes[o + 2]};
        if (s == NektarShape::Tetrahedron && !(em[k][0] <= em[k][1] && em[k][1] <= em[k][2]))
          throw InputError(w + ": element " + int_str(ids[k]) + " has tetrahedron modes " + int_str(em[k][0]) + "," +
                           int_str(em[k][1]) + "," + int_str(em[k][2]) + "; expected P <= Q <= R");
        per_field += static_cast<std::size_t>(nektar_num_coeffs(s, em[k]));
      }
      const std::size_t nvals = names.size() * per_field;
      if (bytes.size() != 8 * nvals)
        throw InputError(w + ": " + int_str(bytes.size() / 8) + (bytes.size() % 8 ? " and a fraction" : "") +
                         " coefficients for " + int_str(ids.size()) + " elements x " + int_str(names.size()) +
                         " fields; expected " + int_str(nvals) + " from NUMMODESPERDIR=" + quote(nm));
      std::vector<double> vals(nvals);
      if (nvals) std::memcpy(vals.data(), bytes.data(), bytes.size());
      for (std::size_t i = 0; i < nvals; ++i)
        if (!std::isfinite(vals[i])) {
          // Locate it: [field][element][mode].
          const std::size_t f = i / per_field;
          std::size_t r = i % per_field, k = 0;
          while (r >= static_cast<std::size_t>(nektar_num_coeffs(s, em[k]))) r -= nektar_num_coeffs(s, em[k++]);
          throw InputError(w + ": non-finite coefficient (" + format_number(vals[i]) + ") of field " +
                           quote(names[f]) + " in element " + int_str(ids[k]) + ", mode " + int_str(r));
        }
      std::size_t offset = 0;
      std::vector<std::size_t> elem_offset(ids.size());
      for (std::size_t k = 0; k < ids.size(); ++k) {
        elem_offset[k] = offset;
        offset += nektar_num_coeffs(s, em[k]);
      }
      for (std::size_t k = 0; k < ids.size(); ++k) {
        NektarFieldElement fe;
        fe.id = ids[k];
        fe.shape = s;
        fe.modes = em[k];
        fe.ncoeffs = nektar_num_coeffs(s, em[k]);
        fe.coeffs.resize(names.size() * fe.ncoeffs);
        for (std::size_t f = 0; f < names.size(); ++f)
          std::copy_n(vals.begin() + f * per_field + elem_offset[k], fe.ncoeffs, fe.coeffs.begin() + f * fe.ncoeffs);
        if (!fld.element_index.emplace(fe.id, static_cast<int>(fld.elements.size())).second)
          throw InputError(w + ": element " + int_str(fe.id) + " appears twice in the field");
        fld.elements.push_back(std::move(fe));
      }
    }
  }
  if (block == 0) throw InputError(what + ": no ELEMENTS block; expected a Nektar++ field file (.fld)");
  return fld;
}

void check_field_matches_mesh(const NektarField& field, const NektarMesh& mesh) {
  for (const auto& fe : field.elements) {
    auto it = mesh.element_index.find(fe.id);
    if (it == mesh.element_index.end())
      throw InputError("read_nektar_field: " + quote(field.path) + ": element " + int_str(fe.id) +
                       " is not in the mesh " + quote(mesh.path) + " (" + int_str(mesh.elements.size()) + " elements)");
    if (mesh.elements[it->second].shape != fe.shape)
      throw InputError("read_nektar_field: " + quote(field.path) + ": element " + int_str(fe.id) + " is a " +
                       nektar_shape_name(fe.shape) + " in the field but a " +
                       nektar_shape_name(mesh.elements[it->second].shape) + " in the mesh " + quote(mesh.path));
  }
}

}  // namespace pm
