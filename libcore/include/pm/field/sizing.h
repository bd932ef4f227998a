#pragma once
// A sizing field h(x) (target edge length / particle spacing, world units)
// sampled on a volume and read with trilinear interpolation in world
// coordinates (SPEC §3 "With a sizing field", Chapter 5).
#include <string>
#include <vector>

#include "pm/base/volume.h"

namespace pm {

class SizingField {
 public:
  /// Copies the voxels as double. The volume's geometry (origin, spacing,
  /// direction matrix) maps world positions to voxels.
  /// \throw InputError naming `name`, the voxel and its value when a voxel is
  /// not finite or h <= 0.
  explicit SizingField(const Volume& h, std::string name = {});

  /// A constant h over `box` (world units): a 2x2x2 grid on the box corners.
  /// \pre h > 0, box not empty.
  static SizingField constant(double h, const Box& box);

  /// h at world position x by trilinear interpolation. Returns false (and
  /// leaves h untouched) when x lies outside the grid's node box.
  bool sample(const Vec3& x, double& h) const;
  /// True when x lies inside the grid's node box.
  bool covers(const Vec3& x) const;

  double min_value() const { return min_; }
  double max_value() const { return max_; }
  /// World bounding box of the voxel nodes.
  const Box& bounds() const { return bounds_; }
  const std::string& name() const { return name_; }

 private:
  Dims dims_;
  Geometry geom_;
  Mat3 inv_dirs_;
  std::vector<double> data_;
  Box bounds_;
  double min_ = 0, max_ = 0;
  std::string name_;
};

}  // namespace pm
