#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "pm/base/error.h"
#include "pm/io/png.h"
#include "test_util.h"

namespace pm {
namespace {

TEST(Png, RoundTripKeepsEveryPixel) {
  Image img(7, 5, 10, 20, 30);  // odd sizes: no row padding assumptions
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      std::uint8_t* p = img.at(x, y);
      p[0] = std::uint8_t(x * 36);
      p[1] = std::uint8_t(y * 60);
      p[2] = std::uint8_t((x * 7 + y * 13) % 256);
    }
  const std::string path = test::temp_dir() + "/a.png";
  write_png(img, path);
  const Image back = read_png(path);
  EXPECT_EQ(back.width, 7);
  EXPECT_EQ(back.height, 5);
  EXPECT_EQ(back.rgb, img.rgb);
  // Top-left pixel first: (6, 0) is x = 6 on the top row.
  EXPECT_EQ(back.at(6, 0)[0], 216);
  EXPECT_EQ(back.at(0, 4)[1], 240);
}

TEST(Png, BadPathsAndBadImages) {
  const std::string dir = test::temp_dir();
  EXPECT_THROW(write_png(Image(2, 2), dir + "/no/such/folder/a.png"), IoError);
  EXPECT_THROW(write_png(Image(), dir + "/empty.png"), InputError);
  Image wrong(3, 3);
  wrong.rgb.pop_back();
  EXPECT_THROW(write_png(wrong, dir + "/wrong.png"), InputError);
  EXPECT_FALSE(std::filesystem::exists(dir + "/empty.png"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/wrong.png"));

  EXPECT_THROW(read_png(dir + "/missing.png"), IoError);
  {
    std::ofstream f(dir + "/text.png");
    f << "this is not a PNG file at all";
  }
  try {
    read_png(dir + "/text.png");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("text.png"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pm
