#include "pm/field/mesh_sdf.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <unordered_map>

#include "pm/base/error.h"
#include "../io/openvdb_plugin.h"

namespace pm {

MeshCheck check_closed(const Mesh& m) {
  std::unordered_map<std::uint64_t, int> edges;
  edges.reserve(m.faces.size() * 2);
  for (const auto& f : m.faces) {
    for (int e = 0; e < 3; ++e) {
      std::uint64_t a = std::uint32_t(f[e]), b = std::uint32_t(f[(e + 1) % 3]);
      if (a > b) std::swap(a, b);
      ++edges[(a << 32) | b];
    }
  }
  MeshCheck c;
  for (const auto& [key, n] : edges) {
    (void)key;
    if (n == 1) ++c.boundary_edges;
    else if (n > 2) ++c.nonmanifold_edges;
  }
  return c;
}

MeshSdfGrid mesh_sdf_grid(const Mesh& m, const MeshSdfParams& p) {
  if (!(p.voxel > 0) || !std::isfinite(p.voxel))
    throw UsageError("mesh_to_sdf: voxel size " + std::to_string(p.voxel) + " is invalid; expected > 0 (world units)");
  if (!(p.band >= 0)) throw UsageError("mesh_to_sdf: band " + std::to_string(p.band) + " is invalid; expected >= 0 voxels");
  if (!(p.padding >= 0)) throw UsageError("mesh_to_sdf: padding must be >= 0 voxels");
  if (m.faces.empty()) throw InputError("mesh_to_sdf: the mesh has no faces; expected a closed triangle mesh");
  const MeshCheck c = check_closed(m);
  if (!c.closed()) {
    std::ostringstream s;
    s << "mesh_to_sdf: the mesh is not closed (" << c.boundary_edges << " boundary edges, " << c.nonmanifold_edges
      << " non-manifold edges); expected every edge in exactly two triangles";
    throw InputError(s.str());
  }
  Box box;
  for (const Vec3& v : m.vertices) {
    if (!is_finite(v)) throw InputError("mesh_to_sdf: the mesh has a non-finite vertex; expected finite coordinates");
    box.extend(v);
  }
  const double pad = p.padding + (p.band > 0 ? 1.0 : 0.0);
  Dims dims;
  Vec3 origin;
  for (int a = 0; a < 3; ++a) {
    const double lo = std::floor(box.lo[a] / p.voxel - pad);
    const double hi = std::ceil(box.hi[a] / p.voxel + pad);
    const double n = hi - lo + 1;
    if (n > double(1u << 31)) throw InputError("mesh_to_sdf: grid too large; choose a larger voxel size");
    origin[a] = lo * p.voxel;
    (a == 0 ? dims.nx : a == 1 ? dims.ny : dims.nz) = std::size_t(n);
  }
  if (double(dims.nx) * double(dims.ny) * double(dims.nz) > double(1u << 31)) {
    std::ostringstream s;
    s << "mesh_to_sdf: a " << dims.nx << "x" << dims.ny << "x" << dims.nz
      << " grid exceeds 2^31 voxels; expected a larger --voxel";
    throw InputError(s.str());
  }
  return {dims, origin};
}

Volume mesh_to_sdf(const Mesh& m, const MeshSdfParams& p) {
  const MeshSdfGrid grid = mesh_sdf_grid(m, p);  // the checks, before OpenVDB is loaded
  return openvdb_plugin().mesh_to_sdf(m, p, grid);
}

}  // namespace pm
