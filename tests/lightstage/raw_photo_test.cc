// Raw photographs through LibRaw, on DNG files written here from known sensor values
// (sim/dng_file.h): the decoded values are linear in the light, the black level is gone, clipped
// channels are found.
#include "lightstage/raw_photo.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "lightstage/errors.h"
#include "lightstage/image_file.h"
#include "sim/dng_file.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

constexpr unsigned kBlack = 256;
constexpr unsigned kWhite = 4095;  // A 12-bit sensor.

// A frame of `rgb` DN above black everywhere, on a sensor of width x height sites.
RawFrame flat_frame(int width, int height, const std::array<double, 3>& rgb_above_black) {
  RawFrame f;
  f.width = width;
  f.height = height;
  f.channels = 3;
  f.bit_depth = 16;
  f.pixels.resize(size_t(width) * height * 3);
  for (size_t i = 0; i < f.pixels.size(); ++i) {
    f.pixels[i] = uint16_t(std::min<double>(kWhite, kBlack + std::round(rgb_above_black[i % 3])));
  }
  return f;
}

std::vector<uint8_t> dng_of(const RawFrame& frame, double exposure_s = 0, int iso = 0) {
  sim::BayerImage bayer = sim::bayer_mosaic(frame, kBlack, kWhite);
  bayer.exposure_s = exposure_s;
  bayer.iso = iso;
  return sim::encode_dng(bayer);
}

// The decoded value of a channel at the frame's centre, as a fraction of the white level above
// black.
double centre(const DecodedRaw& d, int c) {
  return d.frame.at(d.frame.width / 2, d.frame.height / 2, c) / 65535.0;
}

TEST(RawPhoto, ARampOfExposuresDecodesProportionallyBelowSaturation) {
  const std::array<double, 3> per_unit{37.0, 61.0, 23.0};  // DN per unit of exposure.
  for (const auto mode : {RawDecodeOptions::Mode::kDemosaic, RawDecodeOptions::Mode::kBin2x2}) {
    RawDecodeOptions options;
    options.mode = mode;
    for (double exposure = 1; exposure <= 128; exposure *= 2) {
      const std::array<double, 3> dn{per_unit[0] * exposure, per_unit[1] * exposure,
                                     per_unit[2] * exposure};
      const DecodedRaw d = decode_raw_photo(dng_of(flat_frame(64, 48, dn)), "ramp.dng", options);
      EXPECT_EQ(d.frame.width, mode == RawDecodeOptions::Mode::kBin2x2 ? 32 : 64);
      for (int c = 0; c < 3; ++c) {
        const double expected = dn[size_t(c)] / double(kWhite - kBlack);
        SCOPED_TRACE(std::string(to_string(mode)) + " exposure " + std::to_string(exposure) +
                     " channel " + std::to_string(c));
        if (kBlack + dn[size_t(c)] < kWhite) {
          // Within 1% of proportional (and of one 16-bit code, for the dimmest).
          EXPECT_NEAR(centre(d, c), expected, 0.01 * expected + 1.0 / 65535);
        } else {
          EXPECT_EQ(d.frame.at(d.frame.width / 2, d.frame.height / 2, c), 65535);
        }
      }
    }
  }
}

TEST(RawPhoto, TheBlackLevelIsRemovedAndTheLevelsReported) {
  const DecodedRaw d = decode_raw_photo(dng_of(flat_frame(32, 32, {0, 0, 0}), 0.125, 200), "d.dng");
  EXPECT_NEAR(d.black_level, kBlack, 0.5);
  EXPECT_NEAR(d.white_level, kWhite, 0.5);
  for (int c = 0; c < 3; ++c) EXPECT_LE(d.frame.at(16, 16, c), 1);
  EXPECT_NEAR(d.exposure_s, 0.125, 1e-6);
  EXPECT_NEAR(d.iso, 200, 1e-6);
  EXPECT_EQ(d.camera, "lightstage simulated DSLR");
}

TEST(RawPhoto, AClippedChannelIsCensoredAndTheOthersAreNot) {
  // Red far past the white level, green and blue well within it.
  const DecodedRaw d = decode_raw_photo(dng_of(flat_frame(32, 32, {9000, 1000, 500})), "s.dng");
  EXPECT_EQ(d.frame.at(16, 16, 0), 65535);
  EXPECT_LT(d.frame.at(16, 16, 1), 65535);
  EXPECT_LT(d.frame.at(16, 16, 2), 65535);
  EXPECT_GT(d.saturated_pixels[0], 0);
  EXPECT_EQ(d.saturated_pixels[1], 0);
  EXPECT_EQ(d.saturated_pixels[2], 0);
}

TEST(RawPhoto, ASmoothGradientDemosaicsToItsValues) {
  RawFrame f = flat_frame(96, 64, {0, 0, 0});  // Up to 3,405 DN above black: none clips.
  for (int y = 0; y < f.height; ++y) {
    for (int x = 0; x < f.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        f.pixels[(size_t(y) * f.width + x) * 3 + c] = uint16_t(kBlack + 400 + 25 * x + 5 * y * c);
      }
    }
  }
  const DecodedRaw d = decode_raw_photo(dng_of(f), "g.dng");
  double worst = 0;
  for (int y = 4; y < f.height - 4; ++y) {
    for (int x = 4; x < f.width - 4; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double truth = (f.at(x, y, c) - double(kBlack)) / (kWhite - kBlack);
        worst = std::max(worst, std::abs(d.frame.at(x, y, c) / 65535.0 - truth) / truth);
      }
    }
  }
  EXPECT_LT(worst, 0.01);
}

TEST(RawPhoto, AFixedWhiteBalanceScalesEveryFileAlike) {
  RawDecodeOptions options;
  options.white_balance = {0.5, 1.0, 0.25};
  const DecodedRaw d =
      decode_raw_photo(dng_of(flat_frame(32, 32, {1000, 1000, 1000})), "w.dng", options);
  const double g = centre(d, 1);
  EXPECT_NEAR(centre(d, 0) / g, 0.5, 0.005);
  EXPECT_NEAR(centre(d, 2) / g, 0.25, 0.005);
  options.white_balance = {1.0, 0.0, 1.0};
  EXPECT_THROW(decode_raw_photo(dng_of(flat_frame(8, 8, {1, 1, 1})), "w.dng", options), InputError);
}

TEST(RawPhoto, ATruncatedFileIsAnErrorNamingIt) {
  std::vector<uint8_t> bytes = dng_of(flat_frame(32, 32, {100, 100, 100}));
  bytes.resize(bytes.size() / 3);
  try {
    decode_raw_photo(bytes, "cut.dng");
    FAIL() << "a third of a DNG decoded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.dng: "), std::string::npos) << e.what();
  }
}

TEST(RawPhoto, ImageFilesOpenARawFileAsLinearSixteenBit) {
  const testing::TempDir dir;
  const auto path = dir.path() / "IMG_0001.DNG";
  const std::vector<uint8_t> bytes = dng_of(flat_frame(32, 32, {1000, 2000, 3000}));
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  std::string error;
  const auto reader = image_file::open(path, error);
  ASSERT_TRUE(reader) << error;
  EXPECT_EQ(reader->spec().format, image_file::Sample::kUInt16);
  ASSERT_NE(reader->spec().find("lightstage:linear"), nullptr);
  std::vector<float> rows(size_t(32) * 32 * 3);
  ASSERT_TRUE(reader->read_rows(0, 32, image_file::Sample::kFloat, rows.data()));
  EXPECT_NEAR(rows[(16 * 32 + 16) * 3 + 1], 2000.0 / (kWhite - kBlack), 0.01);
  EXPECT_TRUE(is_raw_photo_name("a.nef") && is_raw_photo_name("b.CR3"));
  EXPECT_FALSE(is_raw_photo_name("a.tif"));
}

}  // namespace
}  // namespace ls
