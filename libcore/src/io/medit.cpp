// MEDIT .mesh reader and writers (see pm/io/medit.h).
#include "pm/io/medit.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <utility>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/number_text.h"

namespace pm {
namespace {

using Pair = std::pair<int, int>;

// Writes with one buffer and checks the stream at the end.
class Out {
 public:
  explicit Out(std::string where) : where_(std::move(where)) {}
  std::string s;
  void num(double v) { append_number(s, v); }
  void save(const std::string& path) const {
    std::ofstream os(path, std::ios::binary);
    if (!os) throw IoError(where_ + ": cannot open for writing");
    os.write(s.data(), std::streamsize(s.size()));
    os.close();
    if (!os) throw IoError(where_ + ": write failed (disk full?)");
  }

 private:
  std::string where_;
};

void head(Out& o, WorldFrame frame) {
  o.s += "MeshVersionFormatted 2\n# written by particlemesh " PM_VERSION "\n";
  o.s += std::string("# frame ") + frame_name(frame) + " SPACE=" + frame_name(frame) + "\n";
  o.s += "Dimension 3\n";
}

void vertices(Out& o, const std::vector<Vec3>& v) {
  o.s += "Vertices\n" + std::to_string(v.size()) + "\n";
  for (const Vec3& p : v) {
    o.num(p.x);
    o.s += ' ';
    o.num(p.y);
    o.s += ' ';
    o.num(p.z);
    o.s += " 0\n";
  }
}

// References 1.. for the distinct pairs, ascending, and their comment lines.
std::map<Pair, int> pair_refs(const std::vector<Pair>& pairs, Out& o) {
  std::map<Pair, int> refs;
  for (const Pair& p : pairs) refs.emplace(p, 0);
  int k = 0;
  for (auto& [p, r] : refs) {
    r = ++k;
    o.s += "# triangle reference " + std::to_string(r) + ": label_a " + std::to_string(p.first) + " label_b " +
           std::to_string(p.second) + "\n";
  }
  return refs;
}

void triangles(Out& o, const std::vector<std::array<int, 3>>& t, const std::vector<int>& refs) {
  o.s += "Triangles\n" + std::to_string(t.size()) + "\n";
  for (std::size_t i = 0; i < t.size(); ++i)
    o.s += std::to_string(t[i][0] + 1) + " " + std::to_string(t[i][1] + 1) + " " + std::to_string(t[i][2] + 1) + " " +
           std::to_string(refs[i]) + "\n";
}

}  // namespace

void write_medit(const Mesh& m, const std::string& path, WorldFrame frame) {
  const std::string where = "write_medit: " + quote(path);
  m.validate(where);
  Out o(where);
  head(o, frame);
  std::vector<int> refs(m.faces.size(), 0);
  const auto a = m.face_ints.find("label_a"), b = m.face_ints.find("label_b"), r = m.face_ints.find("ref");
  if (a != m.face_ints.end() && b != m.face_ints.end()) {
    std::vector<Pair> pairs(m.faces.size());
    for (std::size_t f = 0; f < pairs.size(); ++f) pairs[f] = {a->second[f], b->second[f]};
    const auto ids = pair_refs(pairs, o);
    for (std::size_t f = 0; f < pairs.size(); ++f) refs[f] = ids.at(pairs[f]);
  } else if (r != m.face_ints.end()) {
    refs = r->second;
  }
  vertices(o, m.vertices);
  if (!m.faces.empty()) triangles(o, m.faces, refs);
  o.s += "End\n";
  o.save(path);
}

void write_medit_tets(const LabelledTets& t, const std::string& path, WorldFrame frame) {
  const std::string where = "write_medit: " + quote(path);
  t.validate(where);
  Out o(where);
  head(o, frame);
  std::vector<Pair> pairs(t.triangles.size());
  for (std::size_t f = 0; f < pairs.size(); ++f) pairs[f] = {t.triangle_labels[f][0], t.triangle_labels[f][1]};
  const auto ids = pair_refs(pairs, o);
  std::vector<int> refs(pairs.size());
  for (std::size_t f = 0; f < pairs.size(); ++f) refs[f] = ids.at(pairs[f]);
  vertices(o, t.vertices);
  if (!t.triangles.empty()) triangles(o, t.triangles, refs);
  o.s += "Tetrahedra\n" + std::to_string(t.tets.size()) + "\n";
  for (std::size_t i = 0; i < t.tets.size(); ++i) {
    for (int v : t.tets[i]) o.s += std::to_string(v + 1) + " ";
    o.s += std::to_string(t.materials[i]) + "\n";
  }
  o.s += "End\n";
  o.save(path);
}

namespace {

// The reader of both read_medit and read_medit_tets: Tetrahedra are kept
// (vertex indices and references) when `tets` is not null.
Mesh parse_medit(const std::string& path, WorldFrame* frame, std::vector<std::array<int, 4>>* tets,
                 std::vector<int>* tet_refs) {
  const std::string where = "read_medit: " + quote(path);
  require_readable(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(where + ": cannot open");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string d = ss.str();
  std::size_t p = 0, line = 1;
  WorldFrame fr = WorldFrame::lps;
  std::map<int, Pair> pair_of_ref;
  // Next token; comments (# to the end of the line) are skipped, frame and
  // pair comments noted.
  auto token = [&]() -> std::string {
    for (;;) {
      while (p < d.size() && std::isspace(static_cast<unsigned char>(d[p]))) {
        if (d[p] == '\n') ++line;
        ++p;
      }
      if (p < d.size() && d[p] == '#') {
        std::size_t e = d.find('\n', p);
        if (e == std::string::npos) e = d.size();
        const std::string c = d.substr(p, e - p);
        frame_from_comment(c, fr);
        int r = 0, la = 0, lb = 0;
        if (std::sscanf(c.c_str(), "# triangle reference %d: label_a %d label_b %d", &r, &la, &lb) == 3)
          pair_of_ref[r] = {la, lb};
        p = e;
        continue;
      }
      break;
    }
    const std::size_t b = p;
    while (p < d.size() && !std::isspace(static_cast<unsigned char>(d[p]))) ++p;
    return d.substr(b, p - b);
  };
  auto fail = [&](const std::string& what) -> InputError {
    return InputError(where + ": line " + std::to_string(line) + ": " + what);
  };
  auto number = [&](const std::string& what) {
    const std::string t = token();
    if (t.empty()) throw fail(what + ": unexpected end of file (truncated?)");
    char* end = nullptr;
    const double v = std::strtod(t.c_str(), &end);
    if (t.empty() || *end != '\0' || !std::isfinite(v))
      throw fail(what + ": " + quote(t.substr(0, 20)) + " is not a number");
    return v;
  };
  auto count = [&](const std::string& what, std::size_t min_bytes) {
    const double n = number(what + " count");
    if (!(n >= 0) || n != std::floor(n))
      throw fail(what + " count " + format_number(n) + "; expected a non-negative integer");
    if (n * double(min_bytes) > double(d.size() - p) + 1)
      throw fail(what + " count " + format_number(n) + " is more than the rest of the file holds (truncated?)");
    return std::size_t(n);
  };
  if (token() != "MeshVersionFormatted") throw fail("expected \"MeshVersionFormatted\" (a MEDIT .mesh file)");
  number("MeshVersionFormatted");
  Mesh m;
  std::vector<int> refs;
  bool have_vertices = false;
  for (;;) {
    const std::string key = token();
    if (key.empty() || key == "End") break;
    if (key == "Dimension") {
      if (number("Dimension") != 3) throw fail("Dimension is not 3; expected a 3-D mesh");
    } else if (key == "Vertices") {
      const std::size_t n = count("Vertices", 8);
      if (n > std::size_t(std::numeric_limits<int>::max())) throw fail("too many vertices");
      m.vertices.resize(n);
      for (auto& v : m.vertices) {
        for (int c = 0; c < 3; ++c) v[c] = number("Vertices");
        number("Vertices reference");
      }
      have_vertices = true;
    } else if (key == "Triangles" || key == "Quadrilaterals") {
      const int k = key == "Triangles" ? 3 : 4;
      const std::size_t n = count(key, std::size_t(2 * (k + 1)));
      for (std::size_t i = 0; i < n; ++i) {
        int c[4];
        for (int j = 0; j < k; ++j) {
          const double x = number(key);
          if (!(x >= 1) || x != std::floor(x) || x > double(m.vertices.size()))
            throw fail(key + " " + std::to_string(i) + ": vertex " + std::to_string(x) +
                       " is out of range; expected an integer in [1, " + std::to_string(m.vertices.size()) +
                       "] (Vertices must come first)");
          c[j] = int(x) - 1;
        }
        const double r = number(key + " reference");
        if (!(std::fabs(r) <= double(std::numeric_limits<int>::max())) || r != std::floor(r))
          throw fail(key + " " + std::to_string(i) + ": reference " + std::to_string(r) + " is not an int");
        m.faces.push_back({c[0], c[1], c[2]});
        refs.push_back(int(r));
        if (k == 4) {
          m.faces.push_back({c[0], c[2], c[3]});
          refs.push_back(int(r));
        }
      }
    } else if (key == "Tetrahedra" && tets) {
      const std::size_t n = count(key, 10);
      for (std::size_t i = 0; i < n; ++i) {
        std::array<int, 4> c{};
        for (int j = 0; j < 4; ++j) {
          const double x = number(key);
          if (!(x >= 1) || x != std::floor(x) || x > double(m.vertices.size()))
            throw fail(key + " " + std::to_string(i) + ": vertex " + std::to_string(x) +
                       " is out of range; expected an integer in [1, " + std::to_string(m.vertices.size()) +
                       "] (Vertices must come first)");
          c[std::size_t(j)] = int(x) - 1;
        }
        const double r = number(key + " reference");
        if (!(std::fabs(r) <= double(std::numeric_limits<int>::max())) || r != std::floor(r))
          throw fail(key + " " + std::to_string(i) + ": reference " + std::to_string(r) + " is not an int");
        tets->push_back(c);
        tet_refs->push_back(int(r));
      }
    } else if (key == "Edges" || key == "Tetrahedra" || key == "Corners" || key == "Ridges" ||
               key == "RequiredVertices" || key == "Hexahedra" || key == "Prisms") {
      static const std::map<std::string, int> kWords = {{"Edges", 3},       {"Tetrahedra", 5},
                                                        {"Corners", 1},     {"Ridges", 1},
                                                        {"RequiredVertices", 1}, {"Hexahedra", 9},
                                                        {"Prisms", 7}};
      const int w = kWords.at(key);
      const std::size_t n = count(key, std::size_t(2 * w));
      for (std::size_t i = 0; i < n * std::size_t(w); ++i) number(key);
    } else {
      throw fail("section " + quote(key.substr(0, 40)) +
                 " is not read; expected Dimension, Vertices, Triangles, Quadrilaterals, Edges, Tetrahedra or End");
    }
  }
  if (!have_vertices) throw InputError(where + ": no Vertices section");
  if (frame) *frame = fr;
  if (!m.faces.empty()) {
    bool pairs = !pair_of_ref.empty();
    for (int r : refs) pairs = pairs && pair_of_ref.count(r) > 0;
    if (pairs) {
      std::map<Pair, int> index;
      for (const auto& [r, pr] : pair_of_ref) index.emplace(pr, 0);
      int k = 0;
      for (auto& [pr, i] : index) i = k++;
      auto& la = m.face_ints["label_a"];
      auto& lb = m.face_ints["label_b"];
      auto& pi = m.face_ints["pair"];
      for (int r : refs) {
        const Pair& pr = pair_of_ref.at(r);
        la.push_back(pr.first);
        lb.push_back(pr.second);
        pi.push_back(index.at(pr));
      }
    } else {
      m.face_ints["ref"] = refs;
    }
  }
  return m;
}

}  // namespace

Mesh read_medit(const std::string& path, WorldFrame* frame) { return parse_medit(path, frame, nullptr, nullptr); }

bool medit_has_tetrahedra(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t b = line.find_first_not_of(" \t\r");
    if (b != std::string::npos && line.compare(b, 10, "Tetrahedra") == 0) {
      std::string rest = line.substr(b + 10);
      if (rest.find_first_not_of(" \t\r") == std::string::npos && !std::getline(in, rest)) return false;
      return std::atol(rest.c_str()) > 0;
    }
  }
  return false;
}

LabelledTets read_medit_tets(const std::string& path, WorldFrame* frame) {
  LabelledTets t;
  Mesh m = parse_medit(path, frame, &t.tets, &t.materials);
  if (t.tets.empty())
    throw InputError("read_medit: " + quote(path) + ": no Tetrahedra; expected a tetrahedral mesh");
  t.vertices = std::move(m.vertices);
  t.triangles = std::move(m.faces);
  const bool pairs = m.face_ints.count("label_a") > 0;
  for (std::size_t f = 0; f < t.triangles.size(); ++f)
    t.triangle_labels.push_back(pairs ? std::array<int, 2>{m.face_ints["label_a"][f], m.face_ints["label_b"][f]}
                                      : std::array<int, 2>{0, m.face_ints["ref"][f]});
  t.validate("read_medit: " + quote(path));
  return t;
}

}  // namespace pm
