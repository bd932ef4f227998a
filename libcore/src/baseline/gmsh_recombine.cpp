#include "pm/baseline/gmsh_recombine.h"

#include <gmsh.h>

#include <exception>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/base/log.h"

namespace pm {
namespace {

// Gmsh element types (gmsh.h: getElementProperties).
constexpr int kGmshTriangle = 2;
constexpr int kGmshQuad = 3;
constexpr int kSurface = 2;

// Gmsh keeps one global model: initialise it quietly for one call and always
// finalise it, also when Gmsh throws.
struct GmshSession {
  GmshSession() {
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::option::setNumber("General.Verbosity", 0);
  }
  ~GmshSession() {
    try {
      gmsh::finalize();
    } catch (...) {
    }
  }
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;
};

}  // namespace

GmshRecombineResult gmsh_recombine(const Mesh& tri, const GmshRecombineParams& p) {
  tri.validate("gmsh_recombine");
  if (tri.faces.empty()) throw InputError("gmsh_recombine: the mesh has no triangles; expected a triangle surface");
  GmshRecombineResult r;
  r.input_vertices = tri.vertices.size();
  Stopwatch clock;
  try {
    GmshSession session;
    std::string version;
    gmsh::option::getString("General.Version", version);
    r.gmsh_version = version;
    gmsh::model::add("recombine");
    const int surface = gmsh::model::addDiscreteEntity(kSurface);
    std::vector<std::size_t> node_tags(tri.vertices.size());
    std::vector<double> coords(3 * tri.vertices.size());
    for (std::size_t i = 0; i < tri.vertices.size(); ++i) {
      node_tags[i] = i + 1;
      coords[3 * i] = tri.vertices[i].x;
      coords[3 * i + 1] = tri.vertices[i].y;
      coords[3 * i + 2] = tri.vertices[i].z;
    }
    gmsh::model::mesh::addNodes(kSurface, surface, node_tags, coords);
    std::vector<std::size_t> elem_tags(tri.faces.size()), elem_nodes(3 * tri.faces.size());
    for (std::size_t f = 0; f < tri.faces.size(); ++f) {
      elem_tags[f] = f + 1;
      for (int k = 0; k < 3; ++k) elem_nodes[3 * f + std::size_t(k)] = std::size_t(tri.faces[f][std::size_t(k)]) + 1;
    }
    gmsh::model::mesh::addElementsByType(surface, kGmshTriangle, elem_tags, elem_nodes);
    gmsh::option::setNumber("Mesh.RecombinationAlgorithm", p.algorithm);
    gmsh::option::setNumber("Mesh.RecombineOptimizeTopology", p.optimize_topology);
    gmsh::model::mesh::recombine();

    // Read back: the nodes (Gmsh may renumber or, with topology clean-up,
    // add some), then the quads and the triangles left, in Gmsh's order.
    std::vector<std::size_t> tags;
    std::vector<double> xyz, param;
    gmsh::model::mesh::getNodes(tags, xyz, param, -1, -1, false, false);
    std::unordered_map<std::size_t, int> index;
    index.reserve(tags.size());
    r.mesh.vertices.resize(tags.size());
    for (std::size_t i = 0; i < tags.size(); ++i) {
      index[tags[i]] = int(i);
      r.mesh.vertices[i] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
    }
    auto node = [&](std::size_t tag) {
      const auto it = index.find(tag);
      if (it == index.end())
        throw IoError("gmsh_recombine: Gmsh returned an element with the unknown node " + std::to_string(tag));
      return it->second;
    };
    for (const int type : {kGmshQuad, kGmshTriangle}) {
      std::vector<std::size_t> et, en;
      gmsh::model::mesh::getElementsByType(type, et, en, surface);
      const std::size_t k = type == kGmshQuad ? 4 : 3;
      for (std::size_t e = 0; e < et.size(); ++e) {
        std::array<int, 4> f{-1, -1, -1, -1};
        for (std::size_t j = 0; j < k; ++j) f[j] = node(en[k * e + j]);
        r.mesh.faces.push_back(f);
      }
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw IoError(std::string("gmsh_recombine: Gmsh failed: ") + e.what());
  } catch (...) {
    throw IoError("gmsh_recombine: Gmsh failed (its log has the reason)");
  }
  r.mesh.validate("gmsh_recombine");
  r.seconds = clock.seconds();
  return r;
}

}  // namespace pm
