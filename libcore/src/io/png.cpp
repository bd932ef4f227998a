#include "pm/io/png.h"

#include <png.h>

#include <cstring>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"

namespace pm {

Image::Image(int w, int h, std::uint8_t r, std::uint8_t g, std::uint8_t b) : width(w), height(h) {
  if (w <= 0 || h <= 0) {
    width = height = 0;
    return;
  }
  rgb.resize(std::size_t(w) * std::size_t(h) * 3);
  for (std::size_t i = 0; i < rgb.size(); i += 3) {
    rgb[i] = r;
    rgb[i + 1] = g;
    rgb[i + 2] = b;
  }
}

void write_png(const Image& img, const std::string& path) {
  const std::string where = "write_png: " + quote(path);
  if (img.width <= 0 || img.height <= 0)
    throw InputError(where + ": image is " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                     "; expected a positive width and height");
  const std::size_t expected = std::size_t(img.width) * std::size_t(img.height) * 3;
  if (img.rgb.size() != expected)
    throw InputError(where + ": " + std::to_string(img.rgb.size()) + " bytes of pixel data; expected " +
                     std::to_string(expected) + " (width × height × 3)");
  write_atomically(path, [&](const std::string& tmp) {
    png_image pi;
    std::memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    pi.width = png_uint_32(img.width);
    pi.height = png_uint_32(img.height);
    pi.format = PNG_FORMAT_RGB;
    const int ok = png_image_write_to_file(&pi, tmp.c_str(), 0, img.rgb.data(), png_int_32(img.width * 3), nullptr);
    const std::string msg = pi.message;
    png_image_free(&pi);
    if (!ok) throw IoError(where + ": libpng: " + msg);
  });
}

Image read_png(const std::string& path) {
  const std::string where = "read_png: " + quote(path);
  require_readable(path);
  png_image pi;
  std::memset(&pi, 0, sizeof pi);
  pi.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&pi, path.c_str())) {
    const std::string msg = pi.message;
    png_image_free(&pi);
    throw InputError(where + ": not a valid PNG (libpng: " + msg + ")");
  }
  const std::uint64_t pixels = std::uint64_t(pi.width) * std::uint64_t(pi.height);
  if (pixels == 0 || pixels > (std::uint64_t(1) << 28)) {
    png_image_free(&pi);
    throw InputError(where + ": " + std::to_string(pi.width) + "x" + std::to_string(pi.height) +
                     " pixels; expected between 1 and 2^28");
  }
  pi.format = PNG_FORMAT_RGB;
  Image img;
  img.width = int(pi.width);
  img.height = int(pi.height);
  img.rgb.resize(std::size_t(pixels) * 3);
  if (!png_image_finish_read(&pi, nullptr, img.rgb.data(), png_int_32(img.width * 3), nullptr)) {
    const std::string msg = pi.message;
    png_image_free(&pi);
    throw InputError(where + ": cannot decode (libpng: " + msg + ")");
  }
  png_image_free(&pi);
  return img;
}

}  // namespace pm
