// The marching-cubes baseline's triangles by OpenVDB's volumeToMesh (in the
// plugin libpmcore_openvdb, see io/openvdb_plugin.h); baseline.cpp orients them.
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "../io/openvdb_plugin.h"
#include "pm/base/error.h"

namespace pm {

Mesh openvdb_marching_cubes(const Volume& v, double iso, bool material_below) {
  ensure_openvdb_initialized();
  const Dims d = v.dims();
  const std::size_t n = v.count();
  // g < iso' is the material, whichever side the input has it on.
  std::vector<float> g = v.to_float();
  float giso = float(iso);
  if (!material_below) {
    for (float& x : g) x = -x;
    giso = -giso;
  }
  std::size_t below = 0;
  float gmax = -std::numeric_limits<float>::infinity();
  for (float x : g) {
    below += x < giso;
    gmax = std::max(gmax, x);
  }
  if (below == 0 || below == n)
    throw InputError("marching cubes: no voxel is " + std::string(below == 0 ? "inside" : "outside") +
                     " the surface F = " + std::to_string(iso) + "; expected voxels on both sides");
  // The background (everything outside the volume) is outside the material.
  const float background = std::max(gmax, giso) + 1.0f;
  auto grid = openvdb::FloatGrid::create(background);
  const openvdb::CoordBBox bbox(openvdb::Coord(0, 0, 0), openvdb::Coord(int(d.nx) - 1, int(d.ny) - 1, int(d.nz) - 1));
  openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(bbox, g.data());
  openvdb::tools::copyFromDense(dense, *grid, 0.0f);
  openvdb::Mat4d m = openvdb::Mat4d::identity();
  const Geometry& geo = v.geometry();
  for (int a = 0; a < 3; ++a) {
    const Vec3 c = geo.directions.column(a);
    m(a, 0) = c.x;
    m(a, 1) = c.y;
    m(a, 2) = c.z;
  }
  m(3, 0) = geo.origin.x;
  m(3, 1) = geo.origin.y;
  m(3, 2) = geo.origin.z;
  grid->setTransform(openvdb::math::Transform::createLinearTransform(m));

  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> tris;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(*grid, points, tris, quads, double(giso), 0.0);

  Mesh out;
  out.vertices.reserve(points.size());
  for (const auto& p : points) out.vertices.push_back({double(p.x()), double(p.y()), double(p.z())});
  out.faces.reserve(tris.size() + 2 * quads.size());
  for (const auto& t : tris) out.faces.push_back({int(t[0]), int(t[1]), int(t[2])});
  for (const auto& q : quads) {
    const auto& P = out.vertices;
    const double d02 = norm(P[q[0]] - P[q[2]]), d13 = norm(P[q[1]] - P[q[3]]);
    if (d02 <= d13) {
      out.faces.push_back({int(q[0]), int(q[1]), int(q[2])});
      out.faces.push_back({int(q[0]), int(q[2]), int(q[3])});
    } else {
      out.faces.push_back({int(q[0]), int(q[1]), int(q[3])});
      out.faces.push_back({int(q[1]), int(q[2]), int(q[3])});
    }
  }
  return out;
}

}  // namespace pm
