#pragma once
// 8-bit RGB images and PNG files (libpng).
#include <cstdint>
#include <string>
#include <vector>

namespace pm {

/// An 8-bit RGB image, rows top to bottom, pixels left to right.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  ///< width × height × 3 bytes, row-major

  Image() = default;
  /// width × height pixels of one colour (components 0..255).
  Image(int w, int h, std::uint8_t r = 0, std::uint8_t g = 0, std::uint8_t b = 0);
  /// Pointer to the 3 bytes of pixel (x, y); precondition: 0 <= x < width, 0 <= y < height.
  std::uint8_t* at(int x, int y) { return rgb.data() + 3 * (std::size_t(y) * std::size_t(width) + std::size_t(x)); }
  const std::uint8_t* at(int x, int y) const {
    return rgb.data() + 3 * (std::size_t(y) * std::size_t(width) + std::size_t(x));
  }
};

/// Write an 8-bit RGB PNG. Atomic (temporary file + rename).
/// \throw InputError when the image is empty or rgb has the wrong size;
/// IoError when the file cannot be written.
void write_png(const Image& img, const std::string& path);

/// Read any PNG, converted to 8-bit RGB (alpha is composited onto black by libpng).
/// \throw IoError when the file is missing; InputError when it is not a valid
/// PNG or larger than 2^28 pixels.
Image read_png(const std::string& path);

}  // namespace pm
