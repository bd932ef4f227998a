// Gmsh MSH 4.1 ASCII writer and MSH 4.1 / 2.2 reader (see pm/io/gmsh.h).
#include "pm/io/gmsh.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <unordered_map>
#include <vector>

#include "pm/base/error.h"
#include "pm/io/number_text.h"
#include "scan.h"

namespace pm {
namespace {

// The bounding box of the vertices of some cells, as 6 numbers for $Entities.
template <std::size_t N>
std::string bounding_box(const LabelledTets& t, const std::vector<std::array<int, N>>& cells,
                         const std::vector<std::size_t>& idx) {
  Vec3 lo(1e300, 1e300, 1e300), hi(-1e300, -1e300, -1e300);
  for (std::size_t i : idx)
    for (int v : cells[i])
      for (int c = 0; c < 3; ++c) {
        lo[c] = std::min(lo[c], t.vertices[std::size_t(v)][c]);
        hi[c] = std::max(hi[c], t.vertices[std::size_t(v)][c]);
      }
  std::string s;
  for (double v : {lo.x, lo.y, lo.z, hi.x, hi.y, hi.z}) {
    if (!s.empty()) s += ' ';
    append_number(s, v);
  }
  return s;
}

}  // namespace

void write_gmsh(const LabelledTets& t, const std::string& path, WorldFrame frame) {
  const std::string where = "write_gmsh: " + quote(path);
  t.validate(where);
  if (t.tets.empty()) throw InputError(where + ": no tetrahedra; expected at least one to write");
  std::map<int, std::vector<std::size_t>> by_label;
  for (std::size_t i = 0; i < t.tets.size(); ++i) by_label[t.materials[i]].push_back(i);
  std::map<std::array<int, 2>, std::vector<std::size_t>> by_pair;
  for (std::size_t i = 0; i < t.triangles.size(); ++i) by_pair[t.triangle_labels[i]].push_back(i);
  // Volume tags (entity = physical): the labels when all are positive, else
  // 1, 2, ...; surface tags continue above the largest volume tag, so no tag
  // means a volume and a surface at once even for tools that ignore the dimension.
  const bool positive = by_label.begin()->first > 0;
  std::map<int, int> tag;  // label -> volume tag
  int k = 0;
  for (const auto& [l, v] : by_label) tag[l] = positive ? l : ++k;
  const int last_volume = tag.rbegin()->second;
  const long long room = 2147483647LL - static_cast<long long>(by_pair.size());
  if (last_volume > room)
    throw InputError(where + ": material label " + std::to_string(last_volume) + " leaves no room for the " +
                     std::to_string(by_pair.size()) + " surface tags above it; expected labels up to " +
                     std::to_string(room));
  std::map<std::array<int, 2>, int> surface;  // label pair -> surface tag
  int next = last_volume;
  for (const auto& [pr, v] : by_pair) surface[pr] = ++next;

  std::string o;
  o += "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
  o += std::string("$Comments\nwritten by particlemesh " PM_VERSION ", frame ") + frame_name(frame) +
       " SPACE=" + frame_name(frame) + "\n$EndComments\n";
  o += "$PhysicalNames\n" + std::to_string(by_label.size() + by_pair.size()) + "\n";
  for (const auto& [pr, s] : surface)
    o += "2 " + std::to_string(s) + " \"interface_" + std::to_string(pr[0]) + "_" + std::to_string(pr[1]) + "\"\n";
  for (const auto& [l, v] : by_label) o += "3 " + std::to_string(tag[l]) + " \"material_" + std::to_string(l) + "\"\n";
  o += "$EndPhysicalNames\n";
  // Entities: 0 points, 0 curves, one surface per label pair (no bounding
  // curves), one volume per material (no bounding surfaces), each with its
  // bounding box and one physical tag.
  o += "$Entities\n0 0 " + std::to_string(by_pair.size()) + " " + std::to_string(by_label.size()) + "\n";
  for (const auto& [pr, idx] : by_pair) {
    const std::string s = std::to_string(surface[pr]);
    o += s + " " + bounding_box(t, t.triangles, idx) + " 1 " + s + " 0\n";
  }
  for (const auto& [l, idx] : by_label) {
    const std::string v = std::to_string(tag[l]);
    o += v + " " + bounding_box(t, t.tets, idx) + " 1 " + v + " 0\n";
  }
  o += "$EndEntities\n";
  const std::size_t nv = t.vertices.size();
  const int first = tag.begin()->second;
  o += "$Nodes\n1 " + std::to_string(nv) + " 1 " + std::to_string(nv) + "\n";
  o += "3 " + std::to_string(first) + " 0 " + std::to_string(nv) + "\n";
  for (std::size_t i = 0; i < nv; ++i) o += std::to_string(i + 1) + "\n";
  for (const Vec3& p : t.vertices) {
    append_number(o, p.x);
    o += ' ';
    append_number(o, p.y);
    o += ' ';
    append_number(o, p.z);
    o += '\n';
  }
  o += "$EndNodes\n";
  // Element tags: the tetrahedra 1..#T, then the triangles #T+1..#T+#B.
  const std::size_t ne = t.tets.size() + t.triangles.size();
  o += "$Elements\n" + std::to_string(by_label.size() + by_pair.size()) + " " + std::to_string(ne) + " 1 " +
       std::to_string(ne) + "\n";
  std::size_t id = 0;
  for (const auto& [l, idx] : by_label) {
    o += "3 " + std::to_string(tag[l]) + " 4 " + std::to_string(idx.size()) + "\n";
    for (std::size_t i : idx) {
      const auto& c = t.tets[i];
      o += std::to_string(++id) + " " + std::to_string(c[0] + 1) + " " + std::to_string(c[1] + 1) + " " +
           std::to_string(c[2] + 1) + " " + std::to_string(c[3] + 1) + "\n";
    }
  }
  for (const auto& [pr, idx] : by_pair) {
    o += "2 " + std::to_string(surface[pr]) + " 2 " + std::to_string(idx.size()) + "\n";
    for (std::size_t i : idx) {
      const auto& c = t.triangles[i];
      o += std::to_string(++id) + " " + std::to_string(c[0] + 1) + " " + std::to_string(c[1] + 1) + " " +
           std::to_string(c[2] + 1) + "\n";
    }
  }
  o += "$EndElements\n";
  std::ofstream os(path, std::ios::binary);
  if (!os) throw IoError(where + ": cannot open for writing");
  os.write(o.data(), std::streamsize(o.size()));
  os.close();
  if (!os) throw IoError(where + ": write failed (disk full?)");
}

// ---- reader ----

namespace {

// Nodes per element type and the element's dimension (Gmsh's numbering; 0
// nodes = a type we do not know).
struct ElementType {
  int nodes = 0, dim = -1;
};
ElementType element_type(long long t) {
  switch (t) {
    case 15: return {1, 0};
    case 1: return {2, 1};
    case 8: case 26: return {3, 1};
    case 27: return {5, 1};
    case 28: return {6, 1};
    case 2: return {3, 2};
    case 3: return {4, 2};
    case 9: return {6, 2};
    case 10: return {9, 2};
    case 16: return {8, 2};
    case 20: return {9, 2};
    case 21: return {10, 2};
    case 22: return {12, 2};
    case 23: return {15, 2};
    case 24: return {15, 2};
    case 25: return {21, 2};
    case 4: return {4, 3};
    case 5: return {8, 3};
    case 6: return {6, 3};
    case 7: return {5, 3};
    case 11: return {10, 3};
    case 12: return {27, 3};
    case 13: return {18, 3};
    case 14: return {14, 3};
    case 17: return {20, 3};
    case 18: return {15, 3};
    case 19: return {13, 3};
    case 29: return {20, 3};
    case 30: return {35, 3};
    case 31: return {56, 3};
    default: return {};
  }
}
bool is_tet(long long t) { return t == 4 || t == 11 || t == 29 || t == 30 || t == 31; }
bool is_triangle(long long t) { return t == 2 || t == 9 || (t >= 20 && t <= 25); }

class GmshReader {
 public:
  GmshReader(const std::string& data, const std::string& where) : in_(data, where), data_(data) {}

  LabelledTets read(WorldFrame& frame) {
    if (in_.word() != "$MeshFormat") {
      if (data_.compare(0, 2, "(1") == 0 || data_.compare(0, 2, "(0") == 0)
        in_.fail("this is an ANSYS/Fluent .msh file (meshio's default for .msh), not Gmsh; expected \"$MeshFormat\" "
                 "(write it with meshio's file_format=\"gmsh\")");
      in_.fail("expected \"$MeshFormat\" (a Gmsh .msh file)");
    }
    const std::string version = in_.word();
    if (version == "4.1") v4_ = true;
    else if (version == "2.2" || version == "2.1" || version == "2.0") v4_ = false;
    else in_.fail("MSH version " + quote(version) + "; expected 4.1 or 2.2");
    binary_ = in_.integer("$MeshFormat file type", 0, 1) == 1;
    size_t_ = int(in_.integer("$MeshFormat data size", 4, 8));
    if (size_t_ != 4 && size_t_ != 8) in_.fail("$MeshFormat data size " + std::to_string(size_t_) + "; expected 4 or 8");
    if (binary_) {
      in_.next_line();
      const char* one = in_.bytes(4, "$MeshFormat endianness mark");
      int le = 0;
      std::memcpy(&le, one, 4);
      const unsigned char* b = reinterpret_cast<const unsigned char*>(one);
      if (b[0] == 1 && b[1] == 0 && b[2] == 0 && b[3] == 0) big_ = false;
      else if (b[0] == 0 && b[1] == 0 && b[2] == 0 && b[3] == 1) big_ = true;
      else in_.fail("binary $MeshFormat: the integer 1 reads as " + std::to_string(le) + "; expected 1 in either byte order");
    }
    end_section("$MeshFormat");
    while (!in_.at_end()) {
      const std::string key = in_.word();
      if (key == "$Comments") {
        const std::size_t b = in_.pos();
        const std::size_t e = data_.find("$EndComments", b);
        if (e == std::string::npos) in_.fail("$Comments without $EndComments (truncated?)");
        frame_from_comment(data_.substr(b, e - b), frame);
        in_.seek(e);
        in_.word();
      } else if (key == "$PhysicalNames") {
        physical_names();
      } else if (key == "$Entities" && v4_) {
        entities();
      } else if (key == "$Nodes") {
        v4_ ? nodes4() : nodes2();
      } else if (key == "$Elements") {
        v4_ ? elements4() : elements2();
      } else if (key.size() > 1 && key[0] == '$') {
        // Sections we do not read ($PartitionedEntities, $Periodic, $NodeData, ...).
        const std::string end = "$End" + key.substr(1);
        const std::size_t e = data_.find(end, in_.pos());
        if (e == std::string::npos) in_.fail(key + " without " + end + " (truncated?)");
        in_.seek(e + end.size());
      } else {
        in_.fail("expected a section ($Nodes, $Elements, ...), got " + quote(key.substr(0, 40)));
      }
    }
    if (!have_nodes_) in_.fail("no $Nodes section");
    return std::move(t_);
  }

 private:
  void end_section(const std::string& name) {
    const std::string end = "$End" + name.substr(1);
    const std::string w = in_.word();
    if (w != end) in_.fail("expected " + end + ", got " + quote(w.substr(0, 40)) + " (truncated or a bad count?)");
  }
  // A count or size_t: ASCII word, or binary of the data size.
  std::uint64_t size(const std::string& what, std::uint64_t max = std::uint64_t(1) << 40, bool ascii = false) {
    if (!binary_ || ascii) return std::uint64_t(in_.integer(what, 0, (long long)max));
    const std::uint64_t v = in_.uint(size_t_, big_, what);
    if (v > max) in_.fail(what + ": " + std::to_string(v) + " is more than the file holds (truncated or corrupt?)");
    return v;
  }
  long long integer(const std::string& what) {
    if (!binary_) return in_.integer(what, -2147483647LL - 1, 2147483647LL);
    return in_.sint(4, big_, what);
  }
  double real(const std::string& what) {
    const double v = binary_ ? in_.f64(big_, what) : in_.number(what);
    if (!std::isfinite(v)) in_.fail(what + ": " + format_number(v) + "; expected a finite number");
    return v;
  }
  // A count that must fit in the rest of the file at `bytes` bytes each.
  std::uint64_t count(const std::string& what, std::uint64_t bytes, bool ascii = false) {
    const std::uint64_t n = size(what, std::uint64_t(1) << 40, ascii);
    if (n > in_.remaining() / std::max<std::uint64_t>(1, bytes) + 1)
      in_.fail(what + " " + std::to_string(n) + " is more than the file holds (truncated or a bad count?)");
    return n;
  }

  void physical_names() {
    const std::uint64_t n = count("$PhysicalNames count", 6, true);
    for (std::uint64_t i = 0; i < n; ++i) {
      const int dim = int(in_.integer("$PhysicalNames dimension", 0, 3));
      const long long tag = in_.integer("$PhysicalNames tag", -2147483647LL, 2147483647LL);
      std::string rest = in_.line();
      const std::size_t a = rest.find('"'), b = rest.rfind('"');
      if (a == std::string::npos || b == a) in_.fail("$PhysicalNames entry " + std::to_string(i) + ": expected a quoted name");
      names_[{dim, tag}] = rest.substr(a + 1, b - a - 1);
    }
    end_section("$PhysicalNames");
  }

  void entities() {
    if (binary_) in_.next_line();
    std::uint64_t n[4];
    for (int d = 0; d < 4; ++d) n[d] = count("$Entities count", 8);
    for (int d = 0; d < 4; ++d)
      for (std::uint64_t i = 0; i < n[d]; ++i) {
        const std::string what = "$Entities (dimension " + std::to_string(d) + ", entity " + std::to_string(i) + ")";
        const long long tag = integer(what + " tag");
        for (int k = 0; k < (d == 0 ? 3 : 6); ++k) real(what + " bounding box");
        const std::uint64_t np = count(what + " physical tag count", 4);
        std::vector<long long> phys;
        for (std::uint64_t k = 0; k < np; ++k) phys.push_back(integer(what + " physical tag"));
        if (!phys.empty()) entity_physical_[{d, tag}] = phys.front();
        if (d > 0) {
          const std::uint64_t nb = count(what + " bounding entity count", 4);
          for (std::uint64_t k = 0; k < nb; ++k) integer(what + " bounding entity");
        }
      }
    end_section("$Entities");
  }

  void add_node(long long tag, const Vec3& p, const std::string& what) {
    if (!index_.emplace(tag, int(t_.vertices.size())).second)
      in_.fail(what + ": node tag " + std::to_string(tag) + " appears twice");
    t_.vertices.push_back(p);
  }

  void nodes4() {
    if (binary_) in_.next_line();
    const std::uint64_t blocks = count("$Nodes block count", 4), total = count("$Nodes node count", 8);
    size("$Nodes minimum tag");
    size("$Nodes maximum tag");
    t_.vertices.reserve(total);
    std::uint64_t seen = 0;
    for (std::uint64_t b = 0; b < blocks; ++b) {
      const std::string what = "$Nodes block " + std::to_string(b);
      const int dim = int(integer(what + " entity dimension"));
      integer(what + " entity tag");
      const long long parametric = integer(what + " parametric flag");
      const std::uint64_t n = count(what + " node count", 8);
      if (dim < 0 || dim > 3 || (parametric != 0 && parametric != 1))
        in_.fail(what + ": entity dimension " + std::to_string(dim) + ", parametric " + std::to_string(parametric) +
                 "; expected 0..3 and 0 or 1");
      if (seen + n > total) in_.fail(what + ": more nodes than the " + std::to_string(total) + " the header announces");
      std::vector<long long> tags(n);
      for (auto& tg : tags) tg = (long long)size(what + " node tag", std::uint64_t(1) << 62);
      for (std::uint64_t i = 0; i < n; ++i) {
        Vec3 p;
        for (int c = 0; c < 3; ++c) p[c] = real(what + " node coordinates");
        for (int k = 0; k < (parametric ? dim : 0); ++k) real(what + " parametric coordinates");
        add_node(tags[i], p, what);
      }
      seen += n;
    }
    if (seen != total) in_.fail("$Nodes: " + std::to_string(seen) + " nodes in the blocks; expected " + std::to_string(total));
    have_nodes_ = true;
    end_section("$Nodes");
  }

  void nodes2() {
    const std::uint64_t total = count("$Nodes node count", binary_ ? 28 : 8, true);
    if (binary_) in_.next_line();
    t_.vertices.reserve(total);
    for (std::uint64_t i = 0; i < total; ++i) {
      const std::string what = "$Nodes node " + std::to_string(i);
      const long long tag = integer(what + " tag");
      Vec3 p;
      for (int c = 0; c < 3; ++c) p[c] = real(what + " coordinates");
      add_node(tag, p, what);
    }
    have_nodes_ = true;
    end_section("$Nodes");
  }

  int node(long long tag, const std::string& what) {
    const auto it = index_.find(tag);
    if (it == index_.end())
      in_.fail(what + ": node " + std::to_string(tag) + " is not defined; expected a tag from $Nodes (which must come first)");
    return it->second;
  }

  // The material of a tetrahedron of physical tag `phys`, the label pair of a triangle.
  int material(long long phys) {
    const auto it = names_.find({3, phys});
    long long label = 0;
    char tail = 0;
    if (it != names_.end() && std::sscanf(it->second.c_str(), "material_%lld%c", &label, &tail) == 1) return int(label);
    return int(phys);
  }
  std::array<int, 2> pair(long long phys) {
    const auto it = names_.find({2, phys});
    if (it != names_.end()) {
      const std::string& n = it->second;
      const std::size_t u2 = n.rfind('_');
      const std::size_t u1 = u2 == std::string::npos || u2 == 0 ? std::string::npos : n.rfind('_', u2 - 1);
      if (u1 != std::string::npos) {
        char* e1 = nullptr;
        char* e2 = nullptr;
        const std::string sa = n.substr(u1 + 1, u2 - u1 - 1), sb = n.substr(u2 + 1);
        const long a = std::strtol(sa.c_str(), &e1, 10), b = std::strtol(sb.c_str(), &e2, 10);
        if (!sa.empty() && !sb.empty() && *e1 == '\0' && *e2 == '\0')
          return {int(std::min(a, b)), int(std::max(a, b))};
      }
    }
    return {0, int(phys)};
  }

  void add_element(long long type, long long phys, const std::vector<long long>& nodes, const std::string& what) {
    const ElementType et = element_type(type);
    if (is_tet(type)) {
      std::array<int, 4> c{};
      for (int k = 0; k < 4; ++k) c[std::size_t(k)] = node(nodes[std::size_t(k)], what);
      for (std::size_t k = 4; k < nodes.size(); ++k) node(nodes[k], what);
      t_.tets.push_back(c);
      t_.materials.push_back(material(phys));
    } else if (is_triangle(type)) {
      std::array<int, 3> c{};
      for (int k = 0; k < 3; ++k) c[std::size_t(k)] = node(nodes[std::size_t(k)], what);
      t_.triangles.push_back(c);
      t_.triangle_labels.push_back(pair(phys));
    } else if (et.dim == 3) {
      in_.fail(what + ": element type " + std::to_string(type) +
               " is a 3-D element other than a tetrahedron; expected tetrahedra (types 4, 11)");
    }
  }

  void elements4() {
    if (binary_) in_.next_line();
    const std::uint64_t blocks = count("$Elements block count", 4), total = count("$Elements element count", 4);
    size("$Elements minimum tag");
    size("$Elements maximum tag");
    std::uint64_t seen = 0;
    std::vector<long long> nodes;
    for (std::uint64_t b = 0; b < blocks; ++b) {
      const std::string what = "$Elements block " + std::to_string(b);
      const int dim = int(integer(what + " entity dimension"));
      const long long entity = integer(what + " entity tag");
      const long long type = integer(what + " element type");
      const std::uint64_t n = count(what + " element count", 4);
      const ElementType et = element_type(type);
      if (et.nodes == 0) in_.fail(what + ": element type " + std::to_string(type) + " is not known");
      if (et.dim != dim)
        in_.fail(what + ": element type " + std::to_string(type) + " is " + std::to_string(et.dim) +
                 "-D in an entity of dimension " + std::to_string(dim));
      if (seen + n > total) in_.fail(what + ": more elements than the " + std::to_string(total) + " the header announces");
      long long phys = entity;
      if (const auto it = entity_physical_.find({dim, entity}); it != entity_physical_.end()) phys = it->second;
      nodes.resize(std::size_t(et.nodes));
      for (std::uint64_t i = 0; i < n; ++i) {
        const std::string ew = what + " element " + std::to_string(i);
        size(ew + " tag", std::uint64_t(1) << 62);
        for (auto& v : nodes) v = (long long)size(ew + " node", std::uint64_t(1) << 62);
        add_element(type, phys, nodes, ew);
      }
      seen += n;
    }
    if (seen != total) in_.fail("$Elements: " + std::to_string(seen) + " elements in the blocks; expected " + std::to_string(total));
    end_section("$Elements");
  }

  void elements2() {
    const std::uint64_t total = count("$Elements element count", binary_ ? 16 : 4, true);
    std::vector<long long> nodes, tags;
    if (!binary_) {
      for (std::uint64_t i = 0; i < total; ++i) {
        const std::string what = "$Elements element " + std::to_string(i);
        integer(what + " number");
        const long long type = integer(what + " type");
        const ElementType et = element_type(type);
        if (et.nodes == 0) in_.fail(what + ": element type " + std::to_string(type) + " is not known");
        const long long nt = in_.integer(what + " tag count", 0, 64);
        tags.resize(std::size_t(nt));
        for (auto& tg : tags) tg = integer(what + " tag");
        nodes.resize(std::size_t(et.nodes));
        for (auto& v : nodes) v = integer(what + " node");
        add_element(type, tags.empty() ? 0 : tags[0], nodes, what);
      }
    } else {
      in_.next_line();
      std::uint64_t seen = 0;
      while (seen < total) {
        const long long type = in_.sint(4, big_, "$Elements block type");
        const long long n = in_.sint(4, big_, "$Elements block count");
        const long long nt = in_.sint(4, big_, "$Elements block tag count");
        const ElementType et = element_type(type);
        if (et.nodes == 0) in_.fail("$Elements: element type " + std::to_string(type) + " is not known");
        if (n <= 0 || std::uint64_t(n) > total - seen || nt < 0 || nt > 64)
          in_.fail("$Elements block of type " + std::to_string(type) + ": count " + std::to_string(n) + ", " +
                   std::to_string(nt) + " tags; expected at most the " + std::to_string(total - seen) +
                   " elements left and 0..64 tags (corrupt?)");
        tags.resize(std::size_t(nt));
        nodes.resize(std::size_t(et.nodes));
        for (long long i = 0; i < n; ++i) {
          const std::string what = "$Elements element " + std::to_string(seen + std::uint64_t(i));
          in_.sint(4, big_, what + " number");
          for (auto& tg : tags) tg = in_.sint(4, big_, what + " tag");
          for (auto& v : nodes) v = in_.sint(4, big_, what + " node");
          add_element(type, tags.empty() ? 0 : tags[0], nodes, what);
        }
        seen += std::uint64_t(n);
      }
    }
    end_section("$Elements");
  }

  scan::Cursor in_;
  const std::string& data_;
  bool v4_ = true, binary_ = false, big_ = false, have_nodes_ = false;
  int size_t_ = 8;
  std::map<std::pair<int, long long>, std::string> names_;
  std::map<std::pair<int, long long>, long long> entity_physical_;
  std::unordered_map<long long, int> index_;
  LabelledTets t_;
};

}  // namespace

LabelledTets read_gmsh(const std::string& path, WorldFrame* frame) {
  const std::string where = "read_gmsh: " + quote(path);
  const std::string data = scan::slurp(path, where);
  WorldFrame fr = WorldFrame::lps;
  LabelledTets t = GmshReader(data, where).read(fr);
  t.validate(where);
  if (frame) *frame = fr;
  return t;
}

}  // namespace pm
