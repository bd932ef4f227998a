#include "pm/mesh/tet_quality.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <unordered_map>

#include "pm/base/error.h"

namespace pm {
namespace {

constexpr double kRadToDeg = 57.29577951308232;

double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return dot(b - a, cross(c - a, d - a)) / 6.0;
}

std::uint64_t face_key(int a, int b, int c) {
  int v[3] = {a, b, c};
  std::sort(v, v + 3);
  return (std::uint64_t(v[0]) << 42) ^ (std::uint64_t(v[1]) << 21) ^ std::uint64_t(v[2]);
}
std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(a) << 32) | std::uint64_t(std::uint32_t(b));
}

void add(TetStats& s, const std::array<double, 6>& dih, double rr, double vol) {
  ++s.tets;
  s.volume += std::fabs(vol);
  double lo = 180;
  for (double a : dih) {
    lo = std::min(lo, a);
    s.dihedral_min = std::min(s.dihedral_min, a);
    s.dihedral_max = std::max(s.dihedral_max, a);
    ++s.dihedral_hist[std::size_t(std::clamp(int(a / 10), 0, 17))];
  }
  if (lo < 10) ++s.under_10;
  if (lo >= 25 && *std::max_element(dih.begin(), dih.end()) <= 140) ++s.within_25_140;
  if (!(vol > 0)) ++s.non_positive;
  s.rr_min = std::min(s.rr_min, rr);
  s.rr_mean += rr;  // divided at the end
  ++s.rr_hist[std::size_t(std::clamp(int(rr * 10), 0, 9))];
}

Json stats_json(const TetStats& s) {
  Json h = Json::array(), r = Json::array();
  for (auto c : s.dihedral_hist) h.push_back(c);
  for (auto c : s.rr_hist) r.push_back(c);
  return {{"tets", s.tets},
          {"volume", s.volume},
          {"dihedral_min", s.tets ? s.dihedral_min : 0.0},
          {"dihedral_max", s.dihedral_max},
          {"dihedral_hist_10deg", h},
          {"rr_min", s.tets ? s.rr_min : 0.0},
          {"rr_mean", s.rr_mean},
          {"rr_hist_0.1", r},
          {"share_under_10", s.share_under_10()},
          {"share_25_140", s.share_25_140()},
          {"non_positive", s.non_positive}};
}

}  // namespace

std::array<double, 6> tet_dihedrals(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3 p[4] = {a, b, c, d};
  // Outward normals of the faces opposite each corner (sign-independent:
  // each normal points away from its opposite corner).
  Vec3 n[4];
  for (int k = 0; k < 4; ++k) {
    const Vec3& x = p[(k + 1) % 4];
    const Vec3& y = p[(k + 2) % 4];
    const Vec3& z = p[(k + 3) % 4];
    Vec3 m = cross(y - x, z - x);
    if (dot(m, p[k] - x) > 0) m = m * -1.0;
    const double l = norm(m);
    n[k] = l > 0 ? m / l : Vec3{};
  }
  // The dihedral angle at edge (i, j) lies between the faces opposite the
  // other two corners k, l: π − angle(n_k, n_l).
  static const int kEdges[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2}, {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
  std::array<double, 6> out{};
  for (int e = 0; e < 6; ++e) {
    const double cs = std::clamp(dot(n[kEdges[e][2]], n[kEdges[e][3]]), -1.0, 1.0);
    out[std::size_t(e)] = 180.0 - std::acos(cs) * kRadToDeg;
  }
  return out;
}

double tet_radius_ratio(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3 u = b - a, v = c - a, w = d - a;
  const double det = dot(u, cross(v, w));  // 6 V
  if (!(std::fabs(det) > 0)) return 0;
  const double area = 0.5 * (norm(cross(u, v)) + norm(cross(u, w)) + norm(cross(v, w)) + norm(cross(c - b, d - b)));
  const double r_in = std::fabs(det) / 2.0 / area;  // 3V / A
  const Vec3 o = (cross(v, w) * norm2(u) + cross(w, u) * norm2(v) + cross(u, v) * norm2(w)) / (2.0 * det);
  const double r_circ = norm(o);
  return r_circ > 0 ? std::min(1.0, 3.0 * r_in / r_circ) : 0.0;
}

TetQuality tet_quality(const LabelledTets& t) {
  t.validate("tet_quality");
  TetQuality q;
  q.vertices = t.vertices.size();
  struct FaceUse {
    int count = 0;
    int m0 = 0, m1 = 0;
    std::array<int, 3> v{};
  };
  std::unordered_map<std::uint64_t, FaceUse> faces;
  faces.reserve(t.tets.size() * 3);
  static const int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (std::size_t i = 0; i < t.tets.size(); ++i) {
    const auto& c = t.tets[i];
    const Vec3 &a = t.vertices[std::size_t(c[0])], &b = t.vertices[std::size_t(c[1])],
               &cc = t.vertices[std::size_t(c[2])], &d = t.vertices[std::size_t(c[3])];
    const auto dih = tet_dihedrals(a, b, cc, d);
    const double rr = tet_radius_ratio(a, b, cc, d), vol = signed_volume(a, b, cc, d);
    add(q.overall, dih, rr, vol);
    add(q.materials[t.materials[i]], dih, rr, vol);
    for (const auto& f : kFace) {
      FaceUse& u = faces[face_key(c[std::size_t(f[0])], c[std::size_t(f[1])], c[std::size_t(f[2])])];
      (u.count == 0 ? u.m0 : u.m1) = t.materials[i];
      if (u.count == 0) u.v = {c[std::size_t(f[0])], c[std::size_t(f[1])], c[std::size_t(f[2])]};
      ++u.count;
    }
  }
  auto finish = [](TetStats& s) { s.rr_mean = s.tets ? s.rr_mean / double(s.tets) : 0.0; };
  finish(q.overall);
  for (auto& [m, s] : q.materials) finish(s);
  std::unordered_map<std::uint64_t, int> boundary_edges;
  std::unordered_map<std::uint64_t, char> listed_faces;  // boundary and interface faces
  for (const auto& [key, u] : faces) {
    if (u.count >= 3) {
      ++q.overfull_faces;
    } else if (u.count == 1) {
      ++q.boundary_faces;
      listed_faces[key] = 0;
      for (int e = 0; e < 3; ++e) ++boundary_edges[edge_key(u.v[std::size_t(e)], u.v[std::size_t((e + 1) % 3)])];
    } else if (u.m0 != u.m1) {
      ++q.interface_faces;
      listed_faces[key] = 0;
    }
  }
  for (const auto& [e, n] : boundary_edges)
    if (n != 2) ++q.boundary_nonmanifold_edges;
  if (!t.triangles.empty()) {
    q.has_triangles = true;
    for (const auto& f : t.triangles) {
      auto it = listed_faces.find(face_key(f[0], f[1], f[2]));
      if (it == listed_faces.end())
        ++q.triangles_extra;
      else
        it->second = 1;
    }
    for (const auto& [k, seen] : listed_faces)
      if (!seen) ++q.triangles_missing;
  }
  return q;
}

Json to_json(const TetQuality& q) {
  Json mats = Json::object();
  for (const auto& [m, s] : q.materials) mats[std::to_string(m)] = stats_json(s);
  Json j = {{"vertices", q.vertices},
            {"overall", stats_json(q.overall)},
            {"materials", mats},
            {"boundary_faces", q.boundary_faces},
            {"interface_faces", q.interface_faces},
            {"boundary_nonmanifold_edges", q.boundary_nonmanifold_edges},
            {"overfull_faces", q.overfull_faces},
            {"positive", q.overall.non_positive == 0},
            {"boundary_manifold", q.boundary_nonmanifold_edges == 0 && q.overfull_faces == 0}};
  if (q.has_triangles) {
    j["triangles_missing"] = q.triangles_missing;
    j["triangles_extra"] = q.triangles_extra;
    j["triangles_match"] = q.triangles_missing == 0 && q.triangles_extra == 0;
  }
  return j;
}

std::string format_table(const TetQuality& q) {
  std::ostringstream o;
  char line[256];
  std::snprintf(line, sizeof line, "  tetrahedra %zu  vertices %zu  boundary faces %zu  interface faces %zu\n",
                q.overall.tets, q.vertices, q.boundary_faces, q.interface_faces);
  o << line;
  std::snprintf(line, sizeof line, "  positively oriented %s  boundary manifold %s%s\n",
                q.overall.non_positive ? "NO" : "yes",
                q.boundary_nonmanifold_edges == 0 && q.overfull_faces == 0 ? "yes" : "NO",
                !q.has_triangles ? ""
                : q.triangles_missing == 0 && q.triangles_extra == 0
                    ? "  triangles = boundary + interfaces: yes"
                    : "  triangles = boundary + interfaces: NO");
  o << line;
  std::snprintf(line, sizeof line, "  %8s %9s %11s %8s %8s %7s %7s %9s %9s\n", "material", "tets", "volume",
                "dih_min", "dih_max", "rr_min", "rr_mean", "<10deg%", "25-140%");
  o << line;
  auto row = [&](const std::string& name, const TetStats& s) {
    std::snprintf(line, sizeof line, "  %8s %9zu %11.5g %8.2f %8.2f %7.3f %7.3f %9.2f %9.2f\n", name.c_str(), s.tets,
                  s.volume, s.dihedral_min, s.dihedral_max, s.rr_min, s.rr_mean, 100 * s.share_under_10(),
                  100 * s.share_25_140());
    o << line;
  };
  for (const auto& [m, s] : q.materials) row(std::to_string(m), s);
  row("all", q.overall);
  return o.str();
}

std::vector<std::string> check_tet_requirements(const TetQuality& q, const std::string& req) {
  std::vector<std::string> failed;
  std::stringstream ss(req);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item.erase(std::remove_if(item.begin(), item.end(), ::isspace), item.end());
    if (item.empty()) continue;
    bool ok = true;
    if (item == "positive") {
      ok = q.overall.non_positive == 0;
    } else if (item == "boundary_manifold") {
      ok = q.boundary_nonmanifold_edges == 0 && q.overfull_faces == 0;
    } else if (item == "triangles_match") {
      ok = q.has_triangles && q.triangles_missing == 0 && q.triangles_extra == 0;
    } else {
      const std::size_t op = item.find_first_of("<>=");
      const char* kKeys = "dihedral_min dihedral_max rr_min rr_mean share_under_10 share_25_140";
      if (op == std::string::npos || op == 0)
        throw UsageError("requirement \"" + item +
                         "\" is unknown for a tetrahedral mesh; expected positive, boundary_manifold, triangles_match "
                         "or KEY>=V, KEY<=V, KEY=V with KEY in " + kKeys);
      const std::string key = item.substr(0, op);
      const std::string cmp = item.substr(op, op + 1 < item.size() && item[op + 1] == '=' ? 2 : 1);
      const std::string num = item.substr(op + cmp.size());
      char* end = nullptr;
      const double value = std::strtod(num.c_str(), &end);
      if (num.empty() || *end != '\0' || !std::isfinite(value))
        throw UsageError("requirement \"" + item + "\": expected a number after " + cmp + ", got \"" + num + "\"");
      double have = 0;
      if (key == "dihedral_min" || key == "min_dihedral") have = q.overall.dihedral_min;
      else if (key == "dihedral_max" || key == "max_dihedral") have = q.overall.dihedral_max;
      else if (key == "rr_min") have = q.overall.rr_min;
      else if (key == "rr_mean") have = q.overall.rr_mean;
      else if (key == "share_under_10") have = q.overall.share_under_10();
      else if (key == "share_25_140") have = q.overall.share_25_140();
      else
        throw UsageError("requirement \"" + item + "\": unknown key \"" + key +
                         "\" for a tetrahedral mesh; expected " + kKeys + " (min_dihedral, max_dihedral also read)");
      if (cmp == ">=") ok = have >= value;
      else if (cmp == "<=") ok = have <= value;
      else if (cmp == "=" || cmp == "==") ok = have == value;
      else if (cmp == ">") ok = have > value;
      else if (cmp == "<") ok = have < value;
      else throw UsageError("requirement \"" + item + "\": unknown comparison \"" + cmp + "\"");
      if (!ok) item += " (have " + format_number(have) + ")";
    }
    if (!ok) failed.push_back(item);
  }
  return failed;
}

}  // namespace pm
