// The .lp importer: a real RTI set (normals facing the camera, downsizing), .lp sets written from
// the simulator through transfer curves, images moved since the .lp was written.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <iostream>
#include <optional>
#include <tuple>

#include "capture/olat_import.h"
#include "lightstage/errors.h"
#include "physics/envmap.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/dng_file.h"
#include "tests/capture/olat_import_sets.h"

namespace ls::capture {
namespace {

using namespace olat_testing;  // NOLINT(google-build-using-namespace)

// --- Real RTI set
// ---------------------------------------------------------------------------------

TEST(OlatImport, RealRtiSetImportsAndGivesCameraFacingNormals) {
  if (!fs::exists(real_lp())) GTEST_SKIP() << real_lp() << " is absent";
  OlatImportSummary summary;
  const ReflectanceField field = import_olat(real_lp(), {}, &summary);
  EXPECT_EQ(summary.format, OlatFormat::kRtiLp);
  ASSERT_EQ(field.num_lights(), 240);
  EXPECT_EQ(field.width(), 64);
  EXPECT_EQ(field.height(), 43);
  EXPECT_EQ(summary.transfer_undone, "sRGB curve");
  EXPECT_EQ(summary.pixel_format, "8-bit RGB");
  EXPECT_NE(field.source.find("dirs.lp"), std::string::npos);
  expect_finite_nonnegative(field);
  for (int l = 0; l < field.num_lights(); ++l) {
    const FieldLight& light = field.lights()[l];
    EXPECT_EQ(light.led_id, l);
    EXPECT_TRUE(light.valid);
    EXPECT_NEAR(light.dir_in_stage.norm(), 1.0, 1e-9);
    EXPECT_GT(light.dir_in_stage.z(), 0.0) << "light " << l;
  }
  // 45 of 1,981,440 samples sit at code 255 (measured); kept as lower bounds and reported.
  std::cout << "real RTI set: " << summary.saturated_samples << " saturated samples ("
            << 100 * summary.saturated_fraction << "%)\n";
  EXPECT_LT(summary.saturated_fraction, 0.001);

  const relight::NormalMap map = robust_normals(field);
  int facing = 0, unflagged = 0;
  for (int y = 0; y < field.height(); ++y) {
    for (int x = 0; x < field.width(); ++x) {
      for (int c = 0; c < 3; ++c) {
        ASSERT_TRUE(std::isfinite(map.normal.at(x, y, c)));
        ASSERT_TRUE(std::isfinite(map.albedo.at(x, y, c)));
      }
      if (map.flags.at(x, y, 0) != 0) continue;
      ++unflagged;
      facing += map.normal.at(x, y, 2) > 0;
    }
  }
  const double pixels = double(field.width()) * field.height();
  std::cout << "real RTI set: " << map.flagged_pixels << " of " << pixels << " pixels flagged ("
            << 100 * map.flagged_pixels / pixels << "%), " << facing << " of " << unflagged
            << " unflagged face the camera\n";
  // Measured: 0 of 2752 flagged, all 2752 with n_z > 0 (kFacingAway would flag the others, so the
  // flagged fraction is what says the frame and the curve are plausible).
  EXPECT_LT(map.flagged_pixels, pixels * 0.1);
  EXPECT_GE(facing, 0.95 * unflagged);

  // Frame check on real data: the relief bulges toward the camera, so with x right and y up its
  // normals lean toward -x on the left edge, +x on the right, +y at the top, -y at the bottom.
  Eigen::Vector4d lean = Eigen::Vector4d::Zero();  // Mean n_x left, right; n_y top, bottom.
  Eigen::Vector4d count = Eigen::Vector4d::Zero();
  for (int y = 0; y < field.height(); ++y) {
    for (int x = 0; x < field.width(); ++x) {
      if (map.flags.at(x, y, 0) != 0) continue;
      // Left, right, top and bottom quarters (a corner pixel is in two).
      const bool in_region[4] = {x < field.width() / 4, x >= field.width() * 3 / 4,
                                 y < field.height() / 4, y >= field.height() * 3 / 4};
      for (int r = 0; r < 4; ++r) {
        if (!in_region[r]) continue;
        lean[r] += map.normal.at(x, y, r < 2 ? 0 : 1);
        ++count[r];
      }
    }
  }
  lean = lean.cwiseQuotient(count);
  std::cout << "real RTI set: mean n_x left " << lean[0] << ", right " << lean[1]
            << "; mean n_y top " << lean[2] << ", bottom " << lean[3] << "\n";
  // Measured: -0.15, +0.23, +0.18, -0.27. A flipped x or y in the .lp mapping flips the sign of
  // that pair (the relief would look concave along it).
  EXPECT_LT(lean[0], -0.05);
  EXPECT_GT(lean[1], 0.05);
  EXPECT_GT(lean[2], 0.05);
  EXPECT_LT(lean[3], -0.05);

  const physics::EnvironmentMap env =
      physics::EnvironmentMap::load(ls::testing::source_dir() / "data/envmaps/sky_sun.exr");
  std::vector<Eigen::Vector3d> dirs;
  for (const FieldLight& light : field.lights()) dirs.push_back(light.dir_in_stage);
  const relight::LightWeights weights = relight::integrate_environment(env, dirs);
  const Image relit = relight::relight(field, weights);
  ASSERT_EQ(relit.width, 64);
  double sum = 0;
  for (float v : relit.pixels) {
    ASSERT_TRUE(std::isfinite(v));
    sum += v;
  }
  EXPECT_GT(sum, 0.0);
}

TEST(OlatImport, MaxSizeDownsizesByAreaAveraging) {
  if (!fs::exists(real_lp())) GTEST_SKIP() << real_lp() << " is absent";
  OlatImportOptions options;
  options.max_size = 32;
  OlatImportSummary summary;
  const ReflectanceField small = import_rti_lp(real_lp().parent_path(), options, &summary);
  EXPECT_EQ(small.width(), 32);
  EXPECT_EQ(small.height(), 22);  // 43 * 32 / 64 = 21.5, rounded.
  EXPECT_EQ(summary.source_width, 64);
  expect_finite_nonnegative(small);
  // Area averaging keeps the mean of each image (to the half-pixel row the rounding adds).
  const ReflectanceField full = import_rti_lp(real_lp(), {});
  double mean_full = 0, mean_small = 0;
  for (int y = 0; y < full.height(); ++y) {
    for (int x = 0; x < full.width(); ++x) mean_full += full.at(x, y, 0, 1);
  }
  for (int y = 0; y < small.height(); ++y) {
    for (int x = 0; x < small.width(); ++x) mean_small += small.at(x, y, 0, 1);
  }
  mean_full /= full.width() * full.height();
  mean_small /= small.width() * small.height();
  EXPECT_NEAR(mean_small, mean_full, 0.03 * mean_full);
}

// --- .lp sets from the simulator: transfer curves
// -------------------------------------------------

double lp_error(const fs::path& lp, std::optional<TransferCurve> transfer, const SimSet& set,
                double gamma = 2.2) {
  OlatImportOptions options;
  options.transfer = transfer;
  options.gamma = gamma;
  const ReflectanceField field = import_rti_lp(lp, options);
  expect_finite_nonnegative(field);
  return normal_error(robust_normals(field), set).mean_deg;
}

TEST(OlatImport, LpSrgb8BitNeedsItsCurveUndone) {
  ls::testing::TempDir tmp;
  const SimSet set = render_sphere(40, 60);
  const fs::path lp = write_lp(set, tmp.path(), ".png", 8, srgb_encode);
  const double srgb = lp_error(lp, std::nullopt, set);  // Default: sRGB.
  const double gamma = lp_error(lp, TransferCurve::kGamma, set, 2.2);
  const double linear = lp_error(lp, TransferCurve::kLinear, set);
  std::cout << "8-bit sRGB .lp set: mean angular error undoing sRGB " << srgb << " deg, gamma 2.2 "
            << gamma << " deg, nothing (wrong) " << linear << " deg\n";
  // Measured: sRGB 0.037 deg, gamma 2.2 0.20 deg, linear 14.0 deg.
  EXPECT_LT(srgb, 0.2);
  EXPECT_LT(gamma, 1.0);
  EXPECT_GT(gamma, srgb);
  EXPECT_GT(linear, 5.0);
  EXPECT_GT(linear, 20 * srgb);
}

TEST(OlatImport, Lp16BitLinearPngAndTiffNeedNoCurve) {
  ls::testing::TempDir tmp;
  const SimSet set = render_sphere(40, 60);
  for (const std::string extension : {".png", ".tif"}) {
    SCOPED_TRACE(extension);
    const fs::path lp =
        write_lp(set, tmp / extension.substr(1), extension, 16, [](double v) { return v; });
    const double linear = lp_error(lp, TransferCurve::kLinear, set);
    const double srgb = lp_error(lp, TransferCurve::kSrgb, set);  // Wrong for these files.
    std::cout << "16-bit linear " << extension << " .lp set: mean angular error linear " << linear
              << " deg, undoing sRGB (wrong) " << srgb << " deg\n";
    // Measured: linear 0.030 deg, sRGB 10.5 deg for both formats.
    EXPECT_LT(linear, 0.2);
    EXPECT_GT(srgb, 5.0);
  }
}

// A DSLR's raw files (here DNGs written from the simulator's images, 14-bit with a black level):
// decoded linear by LibRaw, so the set is imported without a curve by default.
TEST(OlatImport, LpOfCameraRawFilesImportsLinearByDefault) {
  ls::testing::TempDir tmp;
  const SimSet set = render_sphere(40, 60);
  constexpr unsigned kBlack = 512, kWhite = 16383;
  const double exposure = 0.95 / max_value(set);
  std::string lp = std::to_string(set.images.size()) + "\n";
  fs::create_directories(tmp / "images");
  for (size_t l = 0; l < set.images.size(); ++l) {
    const std::vector<uint16_t> codes = encode_image(
        set.images[l], Eigen::Vector3d::Constant(exposure), 14, [](double v) { return v; },
        kReadNoise, 1000 + l);
    RawFrame frame;
    frame.width = frame.height = set.size;
    frame.channels = 3;
    frame.pixels.resize(codes.size());
    for (size_t i = 0; i < codes.size(); ++i) {
      frame.pixels[i] = uint16_t(kBlack + std::lround(codes[i] / 16383.0 * (kWhite - kBlack)));
    }
    const std::vector<uint8_t> dng = sim::encode_dng(sim::bayer_mosaic(frame, kBlack, kWhite));
    char name[64];
    std::snprintf(name, sizeof(name), "images/IMG_%04zu.DNG", l);
    std::ofstream(tmp / name, std::ios::binary)
        .write(reinterpret_cast<const char*>(dng.data()), std::streamsize(dng.size()));
    lp += std::string(name) + " " + direction_text(set.dirs[l]) + "\n";
  }
  write_text(tmp / "lights.lp", lp);
  OlatImportSummary summary;
  const ReflectanceField field = import_olat(tmp / "lights.lp", {}, &summary);
  EXPECT_EQ(summary.transfer_undone, "none (linear)");
  const double linear = normal_error(robust_normals(field), set).mean_deg;
  const double srgb = lp_error(tmp / "lights.lp", TransferCurve::kSrgb, set);  // Wrong for raw.
  std::cout << "DNG .lp set: mean angular error by default " << linear << " deg, undoing sRGB "
            << "(wrong) " << srgb << " deg\n";
  // Measured 0.35 deg (sRGB: 10.3). A Bayer sensor interpolates 2 of each pixel's 3 colours (the
  // sphere's rim suffers most): the bound is the 16-bit PNG set's 0.2 deg with room for that, well
  // below the wrong curve's.
  EXPECT_LT(linear, 0.5);
  EXPECT_GT(srgb, 5.0);
}

TEST(OlatImport, LpFindsMovedImagesByFileNameAndSaysSo) {
  ls::testing::TempDir tmp;
  std::vector<uint16_t> grey(4 * 4, 100);
  std::string lp = "3\n";
  for (int i = 0; i < 3; ++i) {
    const std::string name = "light_" + std::to_string(i) + ".png";
    write_codes(tmp / "img" / name, 4, 4, 1, grey, 8);
    // Line 1: an absolute path of the capturing machine; 2: relative with backslashes; 3: plain.
    const std::string written = i == 0   ? "C:\\capture\\session 7\\" + name
                                : i == 1 ? "img\\" + name
                                         : "img/" + name;
    lp += written + " 0 " + std::to_string(0.1 * i) + " 1\r\n";
  }
  write_text(tmp / "set.lp", lp);
  OlatImportSummary summary;
  const ReflectanceField field = import_rti_lp(tmp / "set.lp", {}, &summary);
  ASSERT_EQ(field.num_lights(), 3);
  EXPECT_EQ(summary.pixel_format, "8-bit grey");
  // Grey feeds all channels; code 100 through the sRGB curve is 0.1274.
  EXPECT_NEAR(field.at(1, 1, 2, 0), 0.1274, 1e-3);
  EXPECT_EQ(field.at(1, 1, 2, 0), field.at(1, 1, 2, 2));
  std::string notes;
  for (const std::string& note : summary.notes) notes += note + "\n";
  EXPECT_NE(notes.find("backslashes"), std::string::npos) << notes;
  EXPECT_NE(notes.find("same name"), std::string::npos) << notes;
  EXPECT_NE(notes.find("session 7"), std::string::npos) << notes;
}

// A set mixing a grey image among colour ones, or a 16-bit among 8-bit ones, was not taken by one
// camera in one export: refused naming the odd image, its line and what the first one is.
TEST(OlatImport, LpMixingPixelFormatsIsRefusedNamingTheOddImage) {
  for (const auto& [channels, bits, odd] :
       {std::tuple{1, 8, "8-bit grey"}, std::tuple{3, 16, "16-bit colour"}}) {
    ls::testing::TempDir tmp;
    std::string lp = "3\n";
    for (int i = 0; i < 3; ++i) {
      const std::string name = "light_" + std::to_string(i) + ".png";
      const int c = i == 2 ? channels : 3, b = i == 2 ? bits : 8;
      write_codes(tmp / name, 4, 4, c, std::vector<uint16_t>(size_t(4 * 4 * c), 100), b);
      lp += name + " 0 " + std::to_string(0.1 * i) + " 1\n";
    }
    write_text(tmp / "set.lp", lp);
    try {
      (void)import_rti_lp(tmp / "set.lp", {}, nullptr);
      ADD_FAILURE() << odd << " among 8-bit colour images was taken";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), ::testing::HasSubstr("set.lp:4: image format: expected 8-bit colour"));
      EXPECT_THAT(e.what(), ::testing::HasSubstr(std::string("got ") + odd));
      EXPECT_THAT(e.what(), ::testing::HasSubstr("light_2.png"));
    }
  }
}

}  // namespace
}  // namespace ls::capture
