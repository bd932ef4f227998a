#include "pm/field/mesh_sdf.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/io/vdb.h"

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

Volume mesh_to_sdf(const Mesh& m, const MeshSdfParams& p) {
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

  ensure_openvdb_initialized();
  auto xform = openvdb::math::Transform::createLinearTransform(p.voxel);
  std::vector<openvdb::Vec3s> pts;
  pts.reserve(m.vertices.size());
  for (const Vec3& v : m.vertices) pts.emplace_back(float(v.x / p.voxel), float(v.y / p.voxel), float(v.z / p.voxel));
  std::vector<openvdb::Vec3I> tris;
  tris.reserve(m.faces.size());
  for (const auto& f : m.faces) tris.emplace_back(f[0], f[1], f[2]);
  std::vector<openvdb::Vec4I> quads;
  // Exterior band must reach the box corners when an exact distance is asked for.
  const float diag = float(std::sqrt(double(dims.nx * dims.nx + dims.ny * dims.ny + dims.nz * dims.nz)));
  const float ex = p.band > 0 ? float(p.band) : diag + 1.0f;
  const float in = p.band > 0 ? float(p.band) : std::numeric_limits<float>::max();
  openvdb::tools::QuadAndTriangleDataAdapter<openvdb::Vec3s, openvdb::Vec3I> mesh(pts, tris);
  auto grid = openvdb::tools::meshToVolume<openvdb::FloatGrid>(mesh, *xform, ex, in, 0, nullptr);
  // Grid values are in world units (transform voxel size) — sample densely.
  Volume out(VoxelType::f32, dims, Geometry::with_spacing(p.voxel, p.voxel, p.voxel, origin));
  float* data = out.data<float>();
  auto acc = grid->getConstAccessor();
  const openvdb::Coord o(int(std::lround(origin.x / p.voxel)), int(std::lround(origin.y / p.voxel)),
                         int(std::lround(origin.z / p.voxel)));
  // With band == 0 the exterior band spans the whole box, so every voxel holds
  // its exact distance; otherwise voxels beyond the band read ±background.
  for (std::size_t k = 0; k < dims.nz; ++k)
    for (std::size_t j = 0; j < dims.ny; ++j)
      for (std::size_t i = 0; i < dims.nx; ++i) {
        const openvdb::Coord c(o.x() + int(i), o.y() + int(j), o.z() + int(k));
        data[out.index(i, j, k)] = acc.getValue(c);
      }
  return out;
}

}  // namespace pm
