// OpenLIME planes (issue 18): the export read back renders what was built, upright, within the
// 8-bit quantisation; bad folders are refused by file and field.
#include "relight/compact/plane_field.h"

#include <gtest/gtest.h>

#include <fstream>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "tests/relight/compact/compact_fixtures.h"

namespace ls::relight {
namespace {

namespace fs = std::filesystem;

// 8-bit sRGB PSNR of a field's light `l` against `f` rendered there.
double psnr_at(const capture::ReflectanceField& field, int l, const PlaneField& f, bool flip) {
  const Image image = f.relight_point(field.lights()[size_t(l)].dir_in_stage);
  double squared = 0;
  for (int y = 0; y < field.height(); ++y) {
    for (int x = 0; x < field.width(); ++x) {
      for (int c = 0; c < 3; ++c) {
        const int ry = flip ? field.height() - 1 - y : y;
        const double d = 255.0 * (srgb_encode(float(f.gain) * image.at(x, y, c)) -
                                  srgb_encode(float(f.gain) * field.at(x, ry, l, c)));
        squared += d * d;
      }
    }
  }
  return 20 * std::log10(255.0 / std::sqrt(squared / (3.0 * field.width() * field.height())));
}

TEST(PlaneField, OpenLimeExportRendersTheLightsUprightAsBuilt) {
  const auto& field = compact_testing::sim_field(sim::RtiScene::kGlossy);
  const int led = field.num_lights() / 3;
  for (const auto interpolation : {PlaneInterpolation::kRbf, PlaneInterpolation::kBilinear}) {
    PlaneFieldOptions options;
    options.interpolation = interpolation;
    options.planes = 18;
    const PlaneField built = PlaneField::build(field, options);
    testing::TempDir dir;
    const PlaneField lossless = write_openlime(dir / "png", built, "png");
    EXPECT_EQ(lossless.codes, built.codes);  // PNG planes: the bytes as built.
    EXPECT_EQ(lossless.basis, built.basis);
    const PlaneField jpeg = write_openlime(dir / "jpg", built);
    EXPECT_TRUE(fs::exists(dir / "jpg" / "plane_5.jpg"));
    EXPECT_FALSE(fs::exists(dir / "jpg" / "plane_6.jpg"));
    EXPECT_GT(jpeg.stored_bytes, 0u);
    // At an LED the planes reproduce its image (a floor below 8-bit coefficients
    // and 18 planes leave the glossy highlights' detail), upright: far above upside down.
    const double upright = psnr_at(field, led, jpeg, false);
    EXPECT_GT(upright, 27.0) << to_string(interpolation);
    EXPECT_GT(upright, psnr_at(field, led, jpeg, true) + 6.0) << to_string(interpolation);
    EXPECT_NEAR(psnr_at(field, led, built, false), upright, 1.0);  // JPEG at 95 costs < 1 dB.
  }
}

TEST(PlaneField, MalformedFoldersAreRefusedByFileAndField) {
  const auto& field = compact_testing::sim_field(sim::RtiScene::kMatte);
  PlaneFieldOptions options;
  options.planes = 3;
  options.from_data = false;
  testing::TempDir dir;
  write_openlime(dir.path(), PlaneField::build(field, options));
  const auto error = [&] {
    try {
      (void)read_openlime(dir.path());
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  fs::remove(dir / "plane_0.jpg");
  EXPECT_NE(error().find("plane_0.jpg"), std::string::npos) << error();
  std::ofstream(dir / "info.json") << R"({"width": 4, "height": 4, "type": "ptm"})";
  EXPECT_NE(error().find("type"), std::string::npos) << error();
  options.planes = 4;
  EXPECT_THROW((void)PlaneField::build(field, options), InputError);
}

}  // namespace
}  // namespace ls::relight
