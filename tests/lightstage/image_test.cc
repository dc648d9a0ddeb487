#include "lightstage/image.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

#include "lightstage/errors.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

TEST(Image, FloatExrRoundTripsExactlyWithChannelNames) {
  testing::TempDir tmp;
  Image img(17, 9, 4);
  for (size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = float(std::sin(double(i)) * 1e3);
  img.channel_names = {"normal.X", "normal.Y", "normal.Z", "confidence"};
  write_exr(tmp / "a.exr", img);
  const Image back = read_image(tmp / "a.exr");
  ASSERT_EQ(back.width, 17);
  ASSERT_EQ(back.channels, 4);
  // Channel order on reading may differ: compare by name.
  for (int c = 0; c < 4; ++c) {
    const auto it =
        std::find(back.channel_names.begin(), back.channel_names.end(), img.channel_names[c]);
    ASSERT_NE(it, back.channel_names.end());
    const int bc = int(it - back.channel_names.begin());
    for (int y = 0; y < 9; ++y) {
      for (int x = 0; x < 17; ++x) ASSERT_EQ(back.at(x, y, bc), img.at(x, y, c));
    }
  }
}

TEST(Image, RawFramesRoundTripBitExactAtAnyBitDepth) {
  testing::TempDir tmp;
  for (int bits : {8, 12, 16}) {
    RawFrame f;
    f.width = 31;
    f.height = 7;
    f.channels = 3;
    f.bit_depth = bits;
    f.pixels.resize(31 * 7 * 3);
    for (size_t i = 0; i < f.pixels.size(); ++i)
      f.pixels[i] = uint16_t((i * 2654435761u) % (1u << bits));
    write_raw_frame(tmp / "f.png", f);
    const RawFrame back = read_raw_frame(tmp / "f.png", bits);
    EXPECT_EQ(back.pixels, f.pixels) << bits << " bits";
  }
  // No temporary files are left behind.
  int files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(tmp.path())) ++files;
  EXPECT_EQ(files, 1);
}

TEST(Image, TruncatedOrMissingFilesAreInputErrorsNamingTheFile) {
  testing::TempDir tmp;
  Image img(64, 32, 3, 0.5f);
  write_exr(tmp / "whole.exr", img);
  std::ifstream in(tmp / "whole.exr", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), {});
  std::ofstream(tmp / "cut.exr", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  for (const auto& name : {"cut.exr", "absent.exr"}) {
    try {
      read_image(tmp / name);
      ADD_FAILURE() << name;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

// A file written where a folder stands says so, not "...: Success".
TEST(Image, WritingOverAFolderSaysItIsAFolder) {
  testing::TempDir tmp;
  std::filesystem::create_directories(tmp / "maps.exr");
  try {
    write_exr(tmp / "maps.exr", Image(4, 2, 3, 0.5f));
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("maps.exr: cannot write the file there: it is a folder"),
              std::string::npos)
        << e.what();
  }
  EXPECT_TRUE(std::filesystem::is_empty(tmp / "maps.exr"));
}

TEST(Image, AutoExposurePutsTheBrightPercentileNearWhite) {
  Image img(10, 10, 3, 4.0f);
  const double stops = auto_exposure_stops(img);
  EXPECT_NEAR(4.0 * std::exp2(stops), 0.9, 1e-3);
}

TEST(Image, SrgbClampsToTheUnitRangeAndGivesZeroForNan) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (const auto code : {srgb_encode, srgb_decode}) {
    EXPECT_EQ(code(nan), 0.0f);
    EXPECT_EQ(code(-nan), 0.0f);
    EXPECT_EQ(code(-0.5f), 0.0f);
    EXPECT_EQ(code(-inf), 0.0f);
    EXPECT_EQ(code(0.0f), 0.0f);
    EXPECT_FLOAT_EQ(code(1.0f), 1.0f);  // 1.055 - 0.055 in float: within an ulp of 1.
    EXPECT_EQ(code(3.0f), code(1.0f));
    EXPECT_EQ(code(inf), code(1.0f));
  }
  // IEC 61966-2-1 on both sides of the knee, and the two curves inverse to each other.
  EXPECT_FLOAT_EQ(srgb_encode(0.002f), 12.92f * 0.002f);
  EXPECT_NEAR(srgb_encode(0.18f), 0.4613561, 1e-6);
  EXPECT_NEAR(srgb_decode(0.5f), 0.2140411, 1e-6);
  for (float v = 0.0f; v <= 1.0f; v += 1.0f / 64) {
    EXPECT_NEAR(srgb_decode(srgb_encode(v)), v, 2e-6) << v;
  }
  EXPECT_EQ(srgb8_code(nan), 0.0f);
  EXPECT_EQ(srgb8_code(0.5f), 188.0f);
}

TEST(Image, LuminanceIsRec709ForFloatsAndVectors) {
  const float white[3] = {1, 1, 1}, red[3] = {1, 0, 0}, green[3] = {0, 1, 0}, blue[3] = {0, 0, 1};
  EXPECT_FLOAT_EQ(luminance(white), 1.0f);
  EXPECT_FLOAT_EQ(luminance(red), 0.2126f);
  EXPECT_FLOAT_EQ(luminance(green), 0.7152f);
  EXPECT_FLOAT_EQ(luminance(blue), 0.0722f);
  EXPECT_DOUBLE_EQ(luminance(Eigen::Vector3d(1, 1, 1)), 1.0);
  EXPECT_DOUBLE_EQ(luminance(Eigen::Vector3d(2, 0, 0)), 2 * 0.2126);
  EXPECT_DOUBLE_EQ(luminance(Eigen::Vector3d(0, 0.5, 4)), 0.5 * 0.7152 + 4 * 0.0722);
  EXPECT_DOUBLE_EQ(kLuminanceWeights[0] + kLuminanceWeights[1] + kLuminanceWeights[2], 1.0);
  // The float and double forms agree to float precision.
  const float rgb[3] = {0.3f, 2.5f, 0.01f};
  EXPECT_NEAR(luminance(rgb), luminance(Eigen::Vector3d(0.3f, 2.5f, 0.01f)), 1e-6);
}

}  // namespace
}  // namespace ls
