#include "pm/field/sizing.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "pm/base/error.h"

namespace pm {

SizingField::SizingField(const Volume& h, std::string name)
    : dims_(h.dims()), geom_(h.geometry()), inv_dirs_(inverse(h.geometry().directions)),
      bounds_(h.world_bounds()), name_(std::move(name)) {
  data_ = h.to_double();
  min_ = data_.empty() ? 0 : data_[0];
  max_ = min_;
  for (std::size_t k = 0; k < data_.size(); ++k) {
    const double v = data_[k];
    if (!std::isfinite(v) || v <= 0) {
      const std::size_t i = k % dims_.nx, j = (k / dims_.nx) % dims_.ny, l = k / (dims_.nx * dims_.ny);
      std::ostringstream m;
      m << "sizing field " << quote(name_) << ": voxel (" << i << ", " << j << ", " << l << ") has h = " << v
        << "; expected finite h > 0 everywhere";
      throw InputError(m.str());
    }
    min_ = std::min(min_, v);
    max_ = std::max(max_, v);
  }
}

SizingField SizingField::constant(double h, const Box& box) {
  const Vec3 size = box.size();
  Geometry g = Geometry::with_spacing(std::max(size.x, 1e-12), std::max(size.y, 1e-12),
                                      std::max(size.z, 1e-12), box.lo);
  Volume v(VoxelType::f64, Dims{2, 2, 2}, g);
  for (std::size_t k = 0; k < v.count(); ++k) v.set(k, h);
  return SizingField(v, "constant");
}

bool SizingField::covers(const Vec3& x) const {
  const Vec3 t = inv_dirs_ * (x - geom_.origin);
  const double tol = 1e-9;
  for (int a = 0; a < 3; ++a)
    if (!(t[a] >= -tol && t[a] <= double(dims_[a] - 1) + tol)) return false;
  return true;
}

bool SizingField::sample(const Vec3& x, double& h) const {
  const Vec3 t = inv_dirs_ * (x - geom_.origin);
  const double tol = 1e-9;
  std::size_t i0[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    const double n1 = double(dims_[a] - 1);
    if (!(t[a] >= -tol && t[a] <= n1 + tol)) return false;
    const double c = std::clamp(t[a], 0.0, n1);
    if (dims_[a] == 1) {
      i0[a] = 0;
      f[a] = 0;
      continue;
    }
    std::size_t i = std::size_t(c);
    if (i >= dims_[a] - 1) i = dims_[a] - 2;
    i0[a] = i;
    f[a] = c - double(i);
  }
  const std::size_t sx = dims_.nx > 1 ? 1 : 0, sy = dims_.ny > 1 ? dims_.nx : 0,
                    sz = dims_.nz > 1 ? dims_.nx * dims_.ny : 0;
  const std::size_t base = i0[0] + dims_.nx * (i0[1] + dims_.ny * i0[2]);
  double acc = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    const double w = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
    acc += w * data_[base + dx * sx + dy * sy + dz * sz];
  }
  h = acc;
  return true;
}

}  // namespace pm
