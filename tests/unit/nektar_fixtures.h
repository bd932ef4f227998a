#pragma once
// Small Nektar++ files generated in the tests: meshes built from elements
// given by their local vertex order (edges and faces numbered, oriented and
// listed the way Nektar++ requires, with scrambled vertex ids and flipped
// edges so that no listing order equals the local order), and fields whose
// coefficients come from closed forms independent of the evaluator:
//  * hexahedra: a tensor product of cubics g(xi) = a0 + a1 xi + a2 xi^2 + a3 xi^3
//    has Modified_A coefficients (a0-a1+a2-a3, a0+a1+a2+a3, -4 a2, -2 a3)
//    (1 = psi0+psi1, xi = psi1-psi0, xi^2 = 1-4 psi2, xi^3 = xi-2 psi3);
//  * tetrahedra with 3 modes: the expansion is the hierarchical P2 basis,
//    vertex modes lambda_v and edge modes lambda_a lambda_b, so a quadratic
//    u has vertex coefficients u(v) and edge coefficients
//    4 (u(mid) - (u(a) + u(b)) / 2).
#include <array>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "pm/base/vec.h"
#include "pm/io/nektar.h"

namespace pm::test {

struct GenMesh {
  std::vector<std::pair<int, Vec3>> verts;                       // (id, position) in listing order
  std::vector<std::array<int, 3>> edges;                         // (id, v0, v1)
  std::vector<std::pair<int, std::vector<int>>> faces;           // (id, edge ids)
  std::vector<std::pair<int, std::vector<int>>> tets, hexes;     // (id, face ids)
  std::map<std::pair<int, int>, int> edge_of;                    // sorted vertex pair -> edge id
  std::map<std::set<int>, int> face_of;                          // vertex set -> face id
  std::string curved;                                            // raw <CURVED> block, if any
  int next_elem = 0;

  int vertex(const Vec3& p) {
    const int id = static_cast<int>((verts.size() * 7 + 3) % 1000003);  // scrambled ids
    verts.push_back({id, p});
    return id;
  }
  int edge(int a, int b) {
    const auto key = std::make_pair(std::min(a, b), std::max(a, b));
    auto it = edge_of.find(key);
    if (it != edge_of.end()) return it->second;
    const int id = static_cast<int>(edges.size());
    // Every other edge listed backwards.
    if (id % 2) std::swap(a, b);
    edges.push_back({id, a, b});
    edge_of[key] = id;
    return id;
  }
  int face(const std::vector<int>& vs, const std::vector<int>& es) {
    const std::set<int> key(vs.begin(), vs.end());
    auto it = face_of.find(key);
    if (it != face_of.end()) return it->second;
    const int id = static_cast<int>(faces.size());
    faces.push_back({id, es});
    face_of[key] = id;
    return id;
  }
  /// v: vertex ids in local order v0..v3.
  int add_tet(const std::array<int, 4>& v) {
    const int e01 = edge(v[0], v[1]), e12 = edge(v[1], v[2]), e02 = edge(v[0], v[2]);
    const int e03 = edge(v[0], v[3]), e13 = edge(v[1], v[3]), e23 = edge(v[2], v[3]);
    // Nektar++: face 0 and 1 start with edge 0; faces 1..3 start with edges 0..2.
    const int f0 = face({v[0], v[1], v[2]}, {e01, e02, e12});
    const int f1 = face({v[0], v[1], v[3]}, {e01, e03, e13});
    const int f2 = face({v[1], v[2], v[3]}, {e12, e13, e23});
    const int f3 = face({v[0], v[2], v[3]}, {e02, e23, e03});
    tets.push_back({next_elem, {f0, f1, f2, f3}});
    return next_elem++;
  }
  /// v: vertex ids in local order v0..v7.
  int add_hex(const std::array<int, 8>& v) {
    static const int fv[6][4] = {{0, 1, 2, 3}, {0, 1, 5, 4}, {1, 2, 6, 5}, {3, 2, 6, 7}, {0, 3, 7, 4}, {4, 5, 6, 7}};
    std::vector<int> fs;
    for (const auto& f : fv) {
      // Edges of the quad in a scrambled order: 2, 0, 3, 1.
      const int a = v[f[0]], b = v[f[1]], c = v[f[2]], d = v[f[3]];
      fs.push_back(face({a, b, c, d}, {edge(c, d), edge(a, b), edge(d, a), edge(b, c)}));
    }
    hexes.push_back({next_elem, fs});
    return next_elem++;
  }
  Vec3 pos(int id) const {
    for (const auto& v : verts)
      if (v.first == id) return v.second;
    return {};
  }
};

template <class T>
std::string b64z(const std::vector<T>& v) {
  return nektar_b64z_encode(v.data(), v.size() * sizeof(T));
}

inline std::string num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

inline std::string mesh_xml(const GenMesh& m, bool compressed) {
  std::ostringstream o;
  o << "<?xml version=\"1.0\" encoding=\"utf-8\" ?>\n<NEKTAR>\n  <GEOMETRY DIM=\"3\" SPACE=\"3\">\n";
  const std::string c = " COMPRESSED=\"B64Z-LittleEndian\" BITSIZE=\"64\"";
  if (compressed) {
    std::vector<double> vv;  // id as int64 bits, x, y, z
    for (const auto& v : m.verts) {
      std::int64_t id = v.first;
      double d;
      std::memcpy(&d, &id, 8);
      vv.insert(vv.end(), {d, v.second.x, v.second.y, v.second.z});
    }
    o << "    <VERTEX" << c << ">" << b64z(vv) << "</VERTEX>\n";
    std::vector<std::int64_t> ev;
    for (const auto& e : m.edges) ev.insert(ev.end(), {e[0], e[1], e[2]});
    o << "    <EDGE" << c << ">" << b64z(ev) << "</EDGE>\n    <FACE>\n";
    std::vector<std::int64_t> tv, qv;
    for (const auto& f : m.faces) {
      auto& dst = f.second.size() == 3 ? tv : qv;
      dst.push_back(f.first);
      dst.insert(dst.end(), f.second.begin(), f.second.end());
    }
    if (!tv.empty()) o << "      <T" << c << ">" << b64z(tv) << "</T>\n";
    if (!qv.empty()) o << "      <Q" << c << ">" << b64z(qv) << "</Q>\n";
    o << "    </FACE>\n    <ELEMENT>\n";
    std::vector<std::int64_t> av, hv;
    for (const auto& t : m.tets) {
      av.push_back(t.first);
      av.insert(av.end(), t.second.begin(), t.second.end());
    }
    for (const auto& h : m.hexes) {
      hv.push_back(h.first);
      hv.insert(hv.end(), h.second.begin(), h.second.end());
    }
    if (!av.empty()) o << "      <A" << c << ">" << b64z(av) << "</A>\n";
    if (!hv.empty()) o << "      <H" << c << ">" << b64z(hv) << "</H>\n";
    o << "    </ELEMENT>\n";
  } else {
    o << "    <VERTEX>\n";
    for (const auto& v : m.verts)
      o << "      <V ID=\"" << v.first << "\"> " << num(v.second.x) << " " << num(v.second.y) << " " << num(v.second.z)
        << " </V>\n";
    o << "    </VERTEX>\n    <EDGE>\n";
    for (const auto& e : m.edges) o << "      <E ID=\"" << e[0] << "\"> " << e[1] << " " << e[2] << " </E>\n";
    o << "    </EDGE>\n    <FACE>\n";
    for (const auto& f : m.faces) {
      const char* t = f.second.size() == 3 ? "T" : "Q";
      o << "      <" << t << " ID=\"" << f.first << "\">";
      for (int e : f.second) o << " " << e;
      o << " </" << t << ">\n";
    }
    o << "    </FACE>\n    <ELEMENT>\n";
    for (const auto& t : m.tets) {
      o << "      <A ID=\"" << t.first << "\">";
      for (int f : t.second) o << " " << f;
      o << " </A>\n";
    }
    for (const auto& h : m.hexes) {
      o << "      <H ID=\"" << h.first << "\">";
      for (int f : h.second) o << " " << f;
      o << " </H>\n";
    }
    o << "    </ELEMENT>\n";
  }
  o << m.curved;
  o << "    <COMPOSITE>\n      <C ID=\"0\"> A[0] </C>\n    </COMPOSITE>\n    <DOMAIN> C[0] </DOMAIN>\n";
  o << "  </GEOMETRY>\n</NEKTAR>\n";
  return o.str();
}

/// One ELEMENTS block: coefficients [field][element][mode].
struct GenBlock {
  std::string shape = "Hexahedron";
  std::string basis = "Modified_A,Modified_A,Modified_A";
  std::string fields = "u";
  std::string modes = "UNIORDER:4,4,4";
  std::string ids = "0";
  std::vector<double> coeffs;
  bool compressed_attr = true;
};

inline std::string field_xml(const std::vector<GenBlock>& blocks) {
  std::ostringstream o;
  o << "<?xml version=\"1.0\" encoding=\"utf-8\" ?>\n<NEKTAR>\n  <Metadata><Time>0</Time></Metadata>\n";
  for (const auto& b : blocks) {
    o << "  <ELEMENTS FIELDS=\"" << b.fields << "\" SHAPE=\"" << b.shape << "\" BASIS=\"" << b.basis
      << "\" NUMMODESPERDIR=\"" << b.modes << "\" ID=\"" << b.ids << "\"";
    if (b.compressed_attr) o << " COMPRESSED=\"B64Z-LittleEndian\" BITSIZE=\"64\"";
    o << ">" << b64z(b.coeffs) << "</ELEMENTS>\n";
  }
  o << "</NEKTAR>\n";
  return o.str();
}

inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

/// Modified_A coefficients (4 modes) of a cubic a0 + a1 z + a2 z^2 + a3 z^3.
inline std::array<double, 4> cubic_modes(const std::array<double, 4>& a) {
  return {a[0] - a[1] + a[2] - a[3], a[0] + a[1] + a[2] + a[3], -4 * a[2], -2 * a[3]};
}

/// Monomial coefficients in xi of g(c + h xi) for a cubic g with monomial coefficients a.
inline std::array<double, 4> compose_affine(const std::array<double, 4>& a, double c, double h) {
  // g(c + h xi) = sum_k a_k (c + h xi)^k.
  std::array<double, 4> r{0, 0, 0, 0};
  const double binom[4][4] = {{1, 0, 0, 0}, {1, 1, 0, 0}, {1, 2, 1, 0}, {1, 3, 3, 1}};
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j <= k; ++j) r[j] += a[k] * binom[k][j] * std::pow(c, k - j) * std::pow(h, j);
  return r;
}

/// Coefficients (4x4x4, index i + 4 (j + 4 k)) of g1(x) g2(y) g3(z) on an
/// axis-aligned hexahedron whose local vertex 0 is `lo` and 6 is `hi`.
inline std::vector<double> hex_product_coeffs(const std::array<std::array<double, 4>, 3>& g, const Vec3& lo,
                                              const Vec3& hi) {
  std::array<std::array<double, 4>, 3> m;
  for (int a = 0; a < 3; ++a) m[a] = cubic_modes(compose_affine(g[a], 0.5 * (lo[a] + hi[a]), 0.5 * (hi[a] - lo[a])));
  std::vector<double> c(64);
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) c[i + 4 * (j + 4 * k)] = m[0][i] * m[1][j] * m[2][k];
  return c;
}

/// P2 coefficients (3 modes, 10) of a quadratic u on the tetrahedron with
/// local vertices x[0..3] (mode order 000 001 002 010 011 020 100 101 110 200).
inline std::vector<double> tet_p2_coeffs(const std::function<double(const Vec3&)>& u, const std::array<Vec3, 4>& x) {
  auto edge = [&](int a, int b) { return 4 * (u(0.5 * (x[a] + x[b])) - 0.5 * (u(x[a]) + u(x[b]))); };
  return {u(x[0]), u(x[3]), edge(0, 3), u(x[2]), edge(2, 3), edge(0, 2), u(x[1]), edge(1, 3), edge(1, 2), edge(0, 1)};
}

}  // namespace pm::test
