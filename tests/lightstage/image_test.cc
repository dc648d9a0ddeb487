#include "lightstage/image.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

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

}  // namespace
}  // namespace ls
