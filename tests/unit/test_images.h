#pragma once
// Image checks shared by the render unit tests.
#include <cstddef>
#include <cstdint>

#include "pm/base/vec.h"
#include "pm/io/png.h"

namespace pm {
namespace testing {

/// Pixels (outside the top-left legend corner) whose colour is a shade k * c of c.
inline std::size_t pixels_of_shade(const Image& img, const Vec3& c) {
  std::size_t n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      if (x < 80 && y < 40) continue;
      const std::uint8_t* p = img.at(x, y);
      const Vec3 v{p[0] / 255.0, p[1] / 255.0, p[2] / 255.0};
      const double k = dot(v, c) / dot(c, c);
      n += k > 0.2 && norm(v - c * k) < 0.02;
    }
  return n;
}

}  // namespace testing
}  // namespace pm
