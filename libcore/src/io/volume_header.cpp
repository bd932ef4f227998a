#include "pm/io/volume_header.h"

#include <cmath>
#include <sstream>

#include "pm/base/error.h"

namespace pm {

void check_spacing(const std::string& who, const std::string& path, int axis, double s) {
  if (std::isfinite(s) && s > 0) return;
  std::ostringstream m;
  m << who << ": " << quote(path) << ": spacing of axis " << axis << " is " << s << "; expected > 0";
  throw InputError(m.str());
}

void check_volume_header(const std::string& who, const std::string& path, const Dims& dims,
                         const Geometry& g) {
  const std::string where = who + ": " + quote(path);
  for (int a = 0; a < 3; ++a) {
    if (dims[a] == 0) {
      std::ostringstream m;
      m << where << ": axis " << a << " has size 0 (sizes " << dims.nx << " " << dims.ny << " " << dims.nz
        << "); expected every axis >= 1";
      throw InputError(m.str());
    }
  }
  // Overflow-safe product check.
  const std::uint64_t nx = dims.nx, ny = dims.ny, nz = dims.nz;
  if (nx > kMaxVolumeVoxels || ny > kMaxVolumeVoxels / nx || nz > kMaxVolumeVoxels / (nx * ny)) {
    std::ostringstream m;
    m << where << ": sizes " << nx << " " << ny << " " << nz << " make more than 2^34 voxels; "
      << "expected a smaller volume (corrupt header?)";
    throw InputError(m.str());
  }
  for (int a = 0; a < 3; ++a) {
    const Vec3 c = g.directions.column(a);
    if (!is_finite(c)) {
      std::ostringstream m;
      m << where << ": direction of axis " << a << " is (" << c.x << "," << c.y << "," << c.z
        << "); expected finite values";
      throw InputError(m.str());
    }
    check_spacing(who, path, a, g.spacing(a));
  }
  if (!is_finite(g.origin)) {
    std::ostringstream m;
    m << where << ": origin is (" << g.origin.x << "," << g.origin.y << "," << g.origin.z
      << "); expected finite values";
    throw InputError(m.str());
  }
  const double det = determinant(g.directions);
  const double scale = g.spacing(0) * g.spacing(1) * g.spacing(2);
  if (!(std::fabs(det) > 1e-12 * scale)) {
    throw InputError(where + ": the axis directions are linearly dependent; expected three independent axes");
  }
}

}  // namespace pm
