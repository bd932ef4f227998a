#include "pm/baseline/gmsh_recombine.h"

// Gmsh is loaded when the baseline first runs (dlopen of the library the
// header belongs to), not linked: libgmsh pulls in OpenCASCADE, FLTK, X11
// and OpenGL, some 90 shared libraries and 60 ms of start-up for every tool
// run, and only this baseline calls it. The calls go through Gmsh's C API
// (gmshc.h), whose functions are plain C symbols; its types come from the
// header, so a mismatch is a compile error.
#include <dlfcn.h>
#include <gmshc.h>

#include <array>
#include <mutex>
#include <type_traits>
#include <vector>
#include <string>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/base/log.h"

namespace pm {
namespace {

// Gmsh element types (gmsh.h: getElementProperties).
constexpr int kGmshTriangle = 2;
constexpr int kGmshQuad = 3;
constexpr int kSurface = 2;

#define PM_GMSH_SONAME "libgmsh.so." PM_STR(GMSH_API_VERSION_MAJOR) "." PM_STR(GMSH_API_VERSION_MINOR)
#define PM_STR(x) PM_STR2(x)
#define PM_STR2(x) #x

// The C API functions used here (member, Gmsh's symbol), resolved once.
#define PM_GMSH_FUNCTIONS(X)                                                                          \
  X(initialize, gmshInitialize) X(finalize, gmshFinalize) X(set_number, gmshOptionSetNumber)         \
  X(get_string, gmshOptionGetString) X(model_add, gmshModelAdd)                                      \
  X(add_discrete_entity, gmshModelAddDiscreteEntity) X(add_nodes, gmshModelMeshAddNodes)             \
  X(add_elements, gmshModelMeshAddElementsByType) X(recombine, gmshModelMeshRecombine)               \
  X(get_nodes, gmshModelMeshGetNodes) X(get_elements, gmshModelMeshGetElementsByType)                \
  X(last_error, gmshLoggerGetLastError) X(free, gmshFree)

struct GmshApi {
#define PM_GMSH_MEMBER(m, f) decltype(&f) m = nullptr;
  PM_GMSH_FUNCTIONS(PM_GMSH_MEMBER)
#undef PM_GMSH_MEMBER
  std::string error;  // why loading failed (empty: loaded)
};

const GmshApi& gmsh_api() {
  static GmshApi api;
  static std::once_flag once;
  std::call_once(once, [] {
    void* h = dlopen(PM_GMSH_SONAME, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
      const char* e = dlerror();
      api.error = std::string("cannot load Gmsh (" PM_GMSH_SONAME "): ") + (e ? e : "unknown error") +
                  "; install Debian's libgmsh-dev (scripts/setup)";
      return;
    }
    auto get = [&](auto& fn, const char* name) {
      fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(dlsym(h, name));
      if (!fn && api.error.empty()) api.error = std::string("Gmsh (" PM_GMSH_SONAME ") lacks ") + name;
    };
#define PM_GMSH_RESOLVE(m, f) get(api.m, #f);
    PM_GMSH_FUNCTIONS(PM_GMSH_RESOLVE)
#undef PM_GMSH_RESOLVE
  });
  if (!api.error.empty()) throw IoError("gmsh_recombine: " + api.error);
  return api;
}

// Throws IoError with Gmsh's last error when a call set ierr.
void check(const GmshApi& g, int ierr, const char* what) {
  if (ierr == 0) return;
  std::string msg;
  char* e = nullptr;
  int ierr2 = 0;
  g.last_error(&e, &ierr2);
  if (e) {
    msg = e;
    g.free(e);
  }
  throw IoError(std::string("gmsh_recombine: Gmsh failed in ") + what + (msg.empty() ? "" : ": " + msg));
}

// Gmsh keeps one global model: initialise it quietly for one call and always
// finalise it, also when a call fails.
struct GmshSession {
  explicit GmshSession(const GmshApi& g) : g_(g) {
    int ierr = 0;
    g_.initialize(0, nullptr, 0, &ierr);
    check(g_, ierr, "initialize");
    g_.set_number("General.Terminal", 0, &ierr);
    g_.set_number("General.Verbosity", 0, &ierr);
  }
  ~GmshSession() {
    int ierr = 0;
    g_.finalize(&ierr);
  }
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;
  const GmshApi& g_;
};

// An array Gmsh allocated, freed with gmshFree.
template <class T>
struct GmshArray {
  explicit GmshArray(const GmshApi& g) : g_(g) {}
  ~GmshArray() {
    if (p) g_.free(p);
  }
  GmshArray(const GmshArray&) = delete;
  GmshArray& operator=(const GmshArray&) = delete;
  const GmshApi& g_;
  T* p = nullptr;
  std::size_t n = 0;
};

}  // namespace

GmshRecombineResult gmsh_recombine(const Mesh& tri, const GmshRecombineParams& p) {
  tri.validate("gmsh_recombine");
  if (tri.faces.empty()) throw InputError("gmsh_recombine: the mesh has no triangles; expected a triangle surface");
  GmshRecombineResult r;
  r.input_vertices = tri.vertices.size();
  Stopwatch clock;
  const GmshApi& g = gmsh_api();
  GmshSession session(g);
  int ierr = 0;
  {
    char* version = nullptr;
    g.get_string("General.Version", &version, &ierr);
    check(g, ierr, "option::getString");
    if (version) {
      r.gmsh_version = version;
      g.free(version);
    }
  }
  g.model_add("recombine", &ierr);
  check(g, ierr, "model::add");
  const int surface = g.add_discrete_entity(kSurface, -1, nullptr, 0, &ierr);
  check(g, ierr, "model::addDiscreteEntity");
  std::vector<std::size_t> node_tags(tri.vertices.size());
  std::vector<double> coords(3 * tri.vertices.size());
  for (std::size_t i = 0; i < tri.vertices.size(); ++i) {
    node_tags[i] = i + 1;
    coords[3 * i] = tri.vertices[i].x;
    coords[3 * i + 1] = tri.vertices[i].y;
    coords[3 * i + 2] = tri.vertices[i].z;
  }
  g.add_nodes(kSurface, surface, node_tags.data(), node_tags.size(), coords.data(), coords.size(), nullptr, 0, &ierr);
  check(g, ierr, "model::mesh::addNodes");
  std::vector<std::size_t> elem_tags(tri.faces.size()), elem_nodes(3 * tri.faces.size());
  for (std::size_t f = 0; f < tri.faces.size(); ++f) {
    elem_tags[f] = f + 1;
    for (int k = 0; k < 3; ++k) elem_nodes[3 * f + std::size_t(k)] = std::size_t(tri.faces[f][std::size_t(k)]) + 1;
  }
  g.add_elements(surface, kGmshTriangle, elem_tags.data(), elem_tags.size(), elem_nodes.data(), elem_nodes.size(),
                 &ierr);
  check(g, ierr, "model::mesh::addElementsByType");
  g.set_number("Mesh.RecombinationAlgorithm", p.algorithm, &ierr);
  check(g, ierr, "option::setNumber");
  g.set_number("Mesh.RecombineOptimizeTopology", p.optimize_topology, &ierr);
  check(g, ierr, "option::setNumber");
  g.recombine(&ierr);
  check(g, ierr, "model::mesh::recombine");

  // Read back: the nodes (Gmsh may renumber or, with topology clean-up,
  // add some), then the quads and the triangles left, in Gmsh's order.
  GmshArray<std::size_t> tags(g);
  GmshArray<double> xyz(g), param(g);
  g.get_nodes(&tags.p, &tags.n, &xyz.p, &xyz.n, &param.p, &param.n, -1, -1, 0, 0, &ierr);
  check(g, ierr, "model::mesh::getNodes");
  if (xyz.n != 3 * tags.n) throw IoError("gmsh_recombine: Gmsh returned " + std::to_string(xyz.n) +
                                         " coordinates for " + std::to_string(tags.n) + " nodes");
  std::unordered_map<std::size_t, int> index;
  index.reserve(tags.n);
  r.mesh.vertices.resize(tags.n);
  for (std::size_t i = 0; i < tags.n; ++i) {
    index[tags.p[i]] = int(i);
    r.mesh.vertices[i] = {xyz.p[3 * i], xyz.p[3 * i + 1], xyz.p[3 * i + 2]};
  }
  auto node = [&](std::size_t tag) {
    const auto it = index.find(tag);
    if (it == index.end())
      throw IoError("gmsh_recombine: Gmsh returned an element with the unknown node " + std::to_string(tag));
    return it->second;
  };
  for (const int type : {kGmshQuad, kGmshTriangle}) {
    GmshArray<std::size_t> et(g), en(g);
    g.get_elements(type, &et.p, &et.n, &en.p, &en.n, surface, 0, 1, &ierr);
    check(g, ierr, "model::mesh::getElementsByType");
    const std::size_t k = type == kGmshQuad ? 4 : 3;
    if (en.n != k * et.n) throw IoError("gmsh_recombine: Gmsh returned a short element list");
    for (std::size_t e = 0; e < et.n; ++e) {
      std::array<int, 4> f{-1, -1, -1, -1};
      for (std::size_t j = 0; j < k; ++j) f[j] = node(en.p[k * e + j]);
      r.mesh.faces.push_back(f);
    }
  }
  r.mesh.validate("gmsh_recombine");
  r.seconds = clock.seconds();
  return r;
}

}  // namespace pm
