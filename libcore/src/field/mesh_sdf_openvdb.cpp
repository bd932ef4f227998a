// mesh_to_sdf's grid by OpenVDB's meshToVolume (in the plugin
// libpmcore_openvdb, see io/openvdb_plugin.h).
#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include <cmath>
#include <limits>
#include <vector>

#include "../io/openvdb_plugin.h"

namespace pm {

Volume openvdb_mesh_to_sdf(const Mesh& m, const MeshSdfParams& p, const MeshSdfGrid& grid_box) {
  const Dims& dims = grid_box.dims;
  const Vec3& origin = grid_box.origin;
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
