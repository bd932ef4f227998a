#include "pm/mesh/tet_quality.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <unordered_map>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>

#include "pm/base/error.h"

namespace pm {
namespace {

constexpr double kRadToDeg = 57.29577951308232;

double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return dot(b - a, cross(c - a, d - a)) / 6.0;
}

std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(a) << 32) | std::uint64_t(std::uint32_t(b));
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

namespace {

// Cosines of the outward normals of the two faces at each edge (ab, ac, ad,
// bc, bd, cd); the dihedral angle is 180° − acos(cosine).
std::array<double, 6> normal_cosines(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
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
  // other two corners k, l.
  static const int kOther[6][2] = {{2, 3}, {1, 3}, {1, 2}, {0, 3}, {0, 2}, {0, 1}};
  std::array<double, 6> cs{};
  for (int e = 0; e < 6; ++e) cs[std::size_t(e)] = std::clamp(dot(n[kOther[e][0]], n[kOther[e][1]]), -1.0, 1.0);
  return cs;
}

double angle_of(double cosine) { return 180.0 - std::acos(cosine) * kRadToDeg; }

// cos(180° − 10° k), k = 1..17: a dihedral angle is in bin k or above
// exactly when its normal cosine is at least kBin[k - 1].
struct Thresholds {
  std::array<double, 17> bin{};
  double at10, at25, at140;
  Thresholds() {
    for (int k = 1; k <= 17; ++k) bin[std::size_t(k - 1)] = std::cos((180.0 - 10.0 * k) / kRadToDeg);
    at10 = std::cos(170.0 / kRadToDeg);
    at25 = std::cos(155.0 / kRadToDeg);
    at140 = std::cos(40.0 / kRadToDeg);
  }
};
const Thresholds& thresholds() {
  static const Thresholds t;
  return t;
}

void add_tet(TetStats& s, const std::array<double, 6>& cs, double rr, double vol) {
  const Thresholds& th = thresholds();
  ++s.tets;
  s.volume += std::fabs(vol);
  const auto [lo, hi] = std::minmax_element(cs.begin(), cs.end());
  s.dihedral_min = std::min(s.dihedral_min, angle_of(*lo));
  s.dihedral_max = std::max(s.dihedral_max, angle_of(*hi));
  for (double c : cs)
    ++s.dihedral_hist[std::size_t(std::upper_bound(th.bin.begin(), th.bin.end(), c) - th.bin.begin())];
  if (*lo < th.at10) ++s.under_10;
  if (*lo >= th.at25 && *hi <= th.at140) ++s.within_25_140;
  if (!(vol > 0)) ++s.non_positive;
  s.rr_min = std::min(s.rr_min, rr);
  s.rr_mean += rr;  // divided at the end
  ++s.rr_hist[std::size_t(std::clamp(int(rr * 10), 0, 9))];
}

void merge(TetStats& s, const TetStats& o) {
  s.tets += o.tets;
  s.volume += o.volume;
  s.dihedral_min = std::min(s.dihedral_min, o.dihedral_min);
  s.dihedral_max = std::max(s.dihedral_max, o.dihedral_max);
  s.rr_min = std::min(s.rr_min, o.rr_min);
  s.rr_mean += o.rr_mean;
  s.under_10 += o.under_10;
  s.within_25_140 += o.within_25_140;
  s.non_positive += o.non_positive;
  for (std::size_t i = 0; i < s.dihedral_hist.size(); ++i) s.dihedral_hist[i] += o.dihedral_hist[i];
  for (std::size_t i = 0; i < s.rr_hist.size(); ++i) s.rr_hist[i] += o.rr_hist[i];
}

struct Partial {
  TetStats overall;
  std::map<int, TetStats> materials;
};

// One face of one tetrahedron: its sorted corners and where it came from.
struct FaceRec {
  std::uint64_t lo;  // corners 0 and 1 of the sorted triple
  std::uint32_t hi;  // corner 2
  std::uint32_t tet_face;  // 4 tet + local face
  bool operator<(const FaceRec& o) const { return lo != o.lo ? lo < o.lo : hi < o.hi; }
  bool same(const FaceRec& o) const { return lo == o.lo && hi == o.hi; }
};

}  // namespace

std::array<double, 6> tet_dihedrals(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  std::array<double, 6> out = normal_cosines(a, b, c, d);
  for (double& x : out) x = angle_of(x);
  return out;
}

DihedralRange tet_dihedral_range(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const std::array<double, 6> cs = normal_cosines(a, b, c, d);
  const auto [lo, hi] = std::minmax_element(cs.begin(), cs.end());
  return {angle_of(*lo), angle_of(*hi)};
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
  const std::size_t nt = t.tets.size();
  static const int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  // Per-tetrahedron numbers in fixed blocks joined in a fixed order: the
  // floating-point sums do not depend on the thread count.
  std::vector<FaceRec> faces(4 * nt);
  const Partial all = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, nt, 8192), Partial{},
      [&](const tbb::blocked_range<std::size_t>& r, Partial acc) {
        // Materials come in long runs: look the map up only when it changes.
        int last_material = 0;
        TetStats* mat = nullptr;
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          if (!mat || t.materials[i] != last_material) {
            last_material = t.materials[i];
            mat = &acc.materials[last_material];
          }
          const auto& c = t.tets[i];
          const Vec3 &a = t.vertices[std::size_t(c[0])], &b = t.vertices[std::size_t(c[1])],
                     &cc = t.vertices[std::size_t(c[2])], &d = t.vertices[std::size_t(c[3])];
          const std::array<double, 6> cs = normal_cosines(a, b, cc, d);
          const double rr = tet_radius_ratio(a, b, cc, d), vol = signed_volume(a, b, cc, d);
          add_tet(acc.overall, cs, rr, vol);
          add_tet(*mat, cs, rr, vol);
          for (int f = 0; f < 4; ++f) {
            std::uint32_t v[3] = {std::uint32_t(c[std::size_t(kFace[f][0])]), std::uint32_t(c[std::size_t(kFace[f][1])]),
                                  std::uint32_t(c[std::size_t(kFace[f][2])])};
            std::sort(v, v + 3);
            faces[4 * i + std::size_t(f)] = {(std::uint64_t(v[0]) << 32) | v[1], v[2], std::uint32_t(4 * i + std::size_t(f))};
          }
        }
        return acc;
      },
      [](Partial x, const Partial& y) {
        merge(x.overall, y.overall);
        for (const auto& [m, s] : y.materials) merge(x.materials[m], s);
        return x;
      });
  q.overall = all.overall;
  q.materials = all.materials;
  auto finish = [](TetStats& s) { s.rr_mean = s.tets ? s.rr_mean / double(s.tets) : 0.0; };
  finish(q.overall);
  for (auto& [m, s] : q.materials) finish(s);

  // Faces shared by two tetrahedra are neighbours once sorted; the counts
  // below do not depend on the order among equal faces.
  tbb::parallel_sort(faces.begin(), faces.end());
  std::unordered_map<std::uint64_t, int> boundary_edges;
  std::vector<FaceRec> listed;  // boundary and interface faces, sorted
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j].same(faces[i])) ++j;
    const std::size_t count = j - i;
    if (count >= 3) {
      ++q.overfull_faces;
    } else if (count == 1) {
      ++q.boundary_faces;
      listed.push_back(faces[i]);
      const auto& c = t.tets[faces[i].tet_face / 4];
      const int* f = kFace[faces[i].tet_face % 4];
      for (int e = 0; e < 3; ++e)
        ++boundary_edges[edge_key(c[std::size_t(f[e])], c[std::size_t(f[(e + 1) % 3])])];
    } else if (t.materials[faces[i].tet_face / 4] != t.materials[faces[i + 1].tet_face / 4]) {
      ++q.interface_faces;
      listed.push_back(faces[i]);
    }
    i = j;
  }
  for (const auto& [e, n] : boundary_edges)
    if (n != 2) ++q.boundary_nonmanifold_edges;
  if (!t.triangles.empty()) {
    q.has_triangles = true;
    std::vector<char> seen(listed.size(), 0);
    for (const auto& f : t.triangles) {
      std::uint32_t v[3] = {std::uint32_t(f[0]), std::uint32_t(f[1]), std::uint32_t(f[2])};
      std::sort(v, v + 3);
      const FaceRec key{(std::uint64_t(v[0]) << 32) | v[1], v[2], 0};
      const auto it = std::lower_bound(listed.begin(), listed.end(), key);
      if (it == listed.end() || !it->same(key))
        ++q.triangles_extra;
      else
        seen[std::size_t(it - listed.begin())] = 1;
    }
    for (char s : seen)
      if (!s) ++q.triangles_missing;
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
