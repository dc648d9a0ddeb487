// OLAT sets read in bands straight from their images (capture::OlatBands): the values,
// ceilings and attributes of the whole import in any band height and over several passes, and
// the errors of an image that cannot be decoded part-way.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <fstream>
#include <functional>

#include "capture/field.h"
#include "capture/olat_import.h"
#include "lightstage/errors.h"
#include "tests/support/test_support.h"

namespace ls::capture {
namespace {

namespace fs = std::filesystem;

// Every band of `rows` rows, top to bottom, checked against the whole import's values.
void expect_bands_equal_whole(OlatBands& bands, const ReflectanceField& whole, int rows) {
  ReflectanceField band;
  for (int y0 = 0; y0 < whole.height(); y0 += rows) {
    const int y1 = std::min(whole.height(), y0 + rows);
    bands.read_rows(y0, y1, band);
    ASSERT_EQ(band.height(), y1 - y0);
    EXPECT_EQ(band.first_row(), y0);
    EXPECT_EQ(band.frame_height(), whole.height());
    const float* expected = whole.pixel(0, y0);
    EXPECT_TRUE(std::equal(band.values().begin(), band.values().end(), expected))
        << "rows " << y0 << "-" << y1;
  }
}

TEST(OlatBands, TheRealSetInBandsIsTheWholeImportBitForBitOverPasses) {
  const fs::path lp = ls::testing::shared_data_dir() / "rti/loewenkopf_klein/dirs.lp";
  if (!fs::exists(lp)) GTEST_SKIP() << "no shared data at " << lp;
  const ReflectanceField whole = import_olat(lp, {});
  const std::unique_ptr<OlatBands> bands = OlatBands::open(lp, {});
  ASSERT_NE(bands, nullptr);
  ASSERT_EQ(bands->width(), whole.width());
  ASSERT_EQ(bands->height(), whole.height());
  ASSERT_EQ(bands->header().num_lights(), whole.num_lights());
  for (int l = 0; l < whole.num_lights(); ++l) {
    EXPECT_EQ(bands->header().lights()[l].dir_in_stage, whole.lights()[l].dir_in_stage);
    EXPECT_EQ(bands->header().lights()[l].saturates_at, whole.lights()[l].saturates_at);
  }
  EXPECT_EQ(bands->header().source, whole.source);
  // Two passes (the second opens the images again) in bands that do not divide the height.
  expect_bands_equal_whole(*bands, whole, 7);
  expect_bands_equal_whole(*bands, whole, 11);
  // A band above the last one read, alone.
  ReflectanceField band;
  bands->read_rows(3, 5, band);
  EXPECT_TRUE(std::equal(band.values().begin(), band.values().end(), whole.pixel(0, 3)));
}

void write_image8(const fs::path& path, int width, int height, const std::vector<uint8_t>& codes) {
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out);
  ASSERT_TRUE(out->open(path.string(), OIIO::ImageSpec(width, height, 3, OIIO::TypeDesc::UINT8)));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, codes.data()));
  out->close();
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// 8-bit PNGs with a saturated code: each light's ceiling and the saturated samples (kept, or
// zeroed with zero_saturated) as the whole import has them.
TEST(OlatBands, SaturatedCodesAndCeilingsAsTheWholeImport) {
  ls::testing::TempDir tmp;
  std::vector<uint8_t> a(6 * 5 * 3), b(6 * 5 * 3);
  for (size_t i = 0; i < a.size(); ++i) a[i] = uint8_t(20 + 7 * i % 200), b[i] = uint8_t(i % 90);
  a[3 * (2 * 6 + 4) + 1] = 255;  // Pixel (4, 2), green, at the maximum code.
  write_image8(tmp / "a.png", 6, 5, a);
  write_image8(tmp / "b.png", 6, 5, b);
  write_text(tmp / "s.lp", "2\na.png 0 0 1\nb.png 0.6 0 0.8\n");
  for (const bool zero : {false, true}) {
    OlatImportOptions options;
    options.zero_saturated = zero;
    const ReflectanceField whole = import_olat(tmp / "s.lp", options);
    const std::unique_ptr<OlatBands> bands = OlatBands::open(tmp / "s.lp", options);
    ASSERT_NE(bands, nullptr);
    for (int l = 0; l < 2; ++l) {
      EXPECT_EQ(bands->header().lights()[l].saturates_at, whole.lights()[l].saturates_at);
    }
    expect_bands_equal_whole(*bands, whole, 2);
    EXPECT_EQ(whole.at(4, 2, 0, 1) == 0.0f, zero);
  }
}

TEST(OlatBands, DownsizedSetsAreReadWhole) {
  ls::testing::TempDir tmp;
  write_image8(tmp / "a.png", 6, 5, std::vector<uint8_t>(6 * 5 * 3, 50));
  write_text(tmp / "s.lp", "1\na.png 0 0 1\n");
  OlatImportOptions options;
  options.max_size = 3;
  EXPECT_EQ(OlatBands::open(tmp / "s.lp", options), nullptr);
  EXPECT_NE(OlatBands::open(tmp / "s.lp", {}), nullptr);
}

// An image cut short (a copy interrupted, a card pulled), PNG or JPEG (which libjpeg only warns
// of, filling the rest grey): the band that reaches the cut, and the whole import, are an
// InputError naming the .lp line and the image, never values made up.
TEST(OlatBands, AnImageCutShortIsAnErrorNamingItsLine) {
  ls::testing::TempDir tmp;
  std::vector<uint8_t> codes(64 * 64 * 3);
  for (size_t i = 0; i < codes.size(); ++i) codes[i] = uint8_t((i * 2654435761u) >> 24);
  for (const std::string ext : {".png", ".jpg"}) {
    SCOPED_TRACE(ext);
    write_image8(tmp / ("a" + ext), 64, 64, codes);
    write_image8(tmp / ("b" + ext), 64, 64, codes);
    fs::resize_file(tmp / ("b" + ext), fs::file_size(tmp / ("b" + ext)) / 2);
    const fs::path lp = tmp / ("s" + ext + ".lp");
    write_text(lp, "2\na" + ext + " 0 0 1\nb" + ext + " 0 0.6 0.8\n");
    const auto expect_named = [&](const std::function<void()>& read) {
      try {
        read();
        ADD_FAILURE() << "a truncated image was read";
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(lp.filename().string() + ":3"), std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find("b" + ext), std::string::npos) << e.what();
      }
    };
    expect_named([&] { import_olat(lp, {}); });
    expect_named([&] {
      const std::unique_ptr<OlatBands> bands = OlatBands::open(lp, {});
      ASSERT_NE(bands, nullptr);
      ReflectanceField band;
      for (int y0 = 0; y0 < 64; y0 += 8) bands->read_rows(y0, y0 + 8, band);
    });
  }
}

}  // namespace
}  // namespace ls::capture
