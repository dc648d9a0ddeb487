// The importers' errors name the file, line and field; saturated samples are counted.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "capture/olat_import.h"
#include "lightstage/errors.h"
#include "tests/capture/olat_import_sets.h"

namespace ls::capture {
namespace {

using namespace olat_testing;  // NOLINT(google-build-using-namespace)

// The InputError `fn` throws; fails the test when it throws none.
std::string input_error(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError thrown";
  return "";
}

// --- Errors
// ---------------------------------------------------------------------------------------

struct TinySet {
  ls::testing::TempDir tmp;
  TinySet() {
    std::vector<uint16_t> pixels(4 * 4 * 3, 50);
    for (int i = 0; i < 3; ++i) {
      write_codes(tmp / ("a" + std::to_string(i) + ".png"), 4, 4, 3, pixels, 8);
    }
  }
  fs::path lp(const std::string& text) const {
    write_text(tmp / "set.lp", text);
    return tmp / "set.lp";
  }
};

TEST(OlatImport, LpErrorsNameFileLineAndField) {
  TinySet set;
  const std::string good = "a0.png 0 0 1\na1.png 0 1 1\na2.png 1 0 1\n";
  std::string e = input_error([&] { import_rti_lp(set.lp("4\n" + good), {}); });
  EXPECT_NE(e.find("set.lp:1: count"), std::string::npos) << e;
  e = input_error([&] { import_rti_lp(set.lp("2\n" + good), {}); });
  EXPECT_NE(e.find("set.lp:4: count"), std::string::npos) << e;
  e = input_error(
      [&] { import_rti_lp(set.lp("3\na0.png 0 0 1\nmissing.png 0 1 1\na2.png 1 0 1"), {}); });
  EXPECT_NE(e.find("set.lp:3: image: 'missing.png' not found"), std::string::npos) << e;
  // A binary file named as an .lp: its bytes quoted as \xNN, never raw to the terminal.
  e = input_error([&] { import_rti_lp(set.lp(std::string("1\n\x01\xff\x00zz\n", 8)), {}); });
  EXPECT_NE(e.find("set.lp:2: light: expected 'image x y z', got '\\x01\\xff\\x00zz'"),
            std::string::npos)
      << e;
  e = input_error(
      [&] { import_rti_lp(set.lp("3\na0.png 0 0 1\na1.png 0 0 0\na2.png 1 0 1"), {}); });
  EXPECT_NE(e.find("set.lp:3: light direction"), std::string::npos) << e;
  EXPECT_NE(e.find("(0, 0, 0)"), std::string::npos) << e;
  e = input_error(
      [&] { import_rti_lp(set.lp("3\na0.png 0 0 1\na1.png 0 1 1\na2.png nan 0 1"), {}); });
  EXPECT_NE(e.find("set.lp:4: light direction"), std::string::npos) << e;
  // A light behind the object lights nothing the camera sees.
  e = input_error(
      [&] { import_rti_lp(set.lp("3\na0.png 0 0 1\na1.png 0 0 -1\na2.png 1 0 1"), {}); });
  EXPECT_NE(e.find("set.lp:3: light direction: expected a light on the camera's side"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("(0, 0, -1), behind it"), std::string::npos) << e;
  e = input_error(
      [&] { import_rti_lp(set.lp("3\na0.png 0 0 1\na1.png 0 x 1\na2.png 1 0 1"), {}); });
  EXPECT_NE(e.find("set.lp:3: light direction: expected a number, got 'x'"), std::string::npos)
      << e;
  // Components near the largest double: a unit direction all the same (their squares overflow
  // norm(), and the direction once came out 0).
  const auto huge =
      import_rti_lp(set.lp("3\na0.png 0 0 1\na1.png 0 1e308 1e308\na2.png 1 0 1"), {});
  EXPECT_NEAR(huge.lights()[1].dir_in_stage.norm(), 1.0, 1e-12);
  EXPECT_NEAR(huge.lights()[1].dir_in_stage.y(), std::sqrt(0.5), 1e-12);
  // A name longer than the file system allows (a fuzz finding: the file system's error escaped).
  e = input_error([&] {
    import_rti_lp(set.lp("3\na0.png 0 0 1\n" + std::string(300, 'x') + ".png 0 1 1\na2.png 1 0 1"),
                  {});
  });
  EXPECT_NE(e.find("set.lp:3: image: '" + std::string(300, 'x')), std::string::npos) << e;
  e = input_error([&] { import_rti_lp(set.lp("three\n" + good), {}); });
  EXPECT_NE(e.find("set.lp:1: count"), std::string::npos) << e;

  std::vector<uint16_t> bigger(5 * 4 * 3, 50);
  write_codes(set.tmp / "big.png", 5, 4, 3, bigger, 8);
  e = input_error(
      [&] { import_rti_lp(set.lp("3\na0.png 0 0 1\na1.png 0 1 1\nbig.png 1 0 1"), {}); });
  EXPECT_NE(e.find("set.lp:4: image size: expected 4x4"), std::string::npos) << e;
  EXPECT_NE(e.find("got 5x4"), std::string::npos) << e;

  OlatImportOptions bad_gamma;
  bad_gamma.transfer = TransferCurve::kGamma;
  bad_gamma.gamma = -1;
  e = input_error([&] { import_rti_lp(set.lp("3\n" + good), bad_gamma); });
  EXPECT_NE(e.find("gamma"), std::string::npos) << e;
}

TEST(OlatImport, DiligentErrorsNameFileLineAndField) {
  TinySet set;
  const fs::path dir = set.tmp.path();
  write_text(dir / "filenames.txt", "a0.png\na1.png\na2.png\n");
  write_text(dir / "light_directions.txt", "0 0 1\n0 1 1\n1 0 1\n");
  write_text(dir / "light_intensities.txt", "1 1 1\n1 1\n1 1 1\n");
  EXPECT_EQ(detect_olat_format(dir), OlatFormat::kDiligent);
  std::string e = input_error([&] { import_olat(dir, {}); });
  EXPECT_NE(e.find("light_intensities.txt:2: light intensity: expected 3 numbers r g b, got 2"),
            std::string::npos)
      << e;
  write_text(dir / "light_intensities.txt", "1 1 1\n1 0 1\n1 1 1\n");
  e = input_error([&] { import_olat(dir, {}); });
  EXPECT_NE(e.find("light_intensities.txt:2: light intensity: expected three positive"),
            std::string::npos)
      << e;
  write_text(dir / "light_intensities.txt", "1 1 1\n1 1 1\n");
  e = input_error([&] { import_olat(dir, {}); });
  EXPECT_NE(e.find("light_intensities.txt: count: expected 3 lines"), std::string::npos) << e;
  write_text(dir / "light_intensities.txt", "1 1 1\n1 1 1\n1 1 1\n");
  write_text(dir / "light_directions.txt", "0 0 1\n0 1\n1 0 1\n");
  e = input_error([&] { import_olat(dir, {}); });
  EXPECT_NE(e.find("light_directions.txt:2: light direction: expected 3 numbers"),
            std::string::npos)
      << e;
  write_text(dir / "light_directions.txt", "0 0 1\n0 1 1\n1 0 1\n");
  write_codes(dir / "mask.png", 3, 3, 1, std::vector<uint16_t>(9, 255), 8);
  e = input_error([&] { import_olat(dir, {}); });
  EXPECT_NE(e.find("mask.png: size: expected 4x4"), std::string::npos) << e;
  fs::remove(dir / "mask.png");
  write_text(dir / "filenames.txt", "a0.png\nnone.png\na2.png\n");
  e = input_error([&] { import_olat(dir, {}); });
  EXPECT_NE(e.find("filenames.txt:2: image: 'none.png' not found"), std::string::npos) << e;
  // Half a DiLiGenT folder names the missing half, not an .lp file.
  fs::remove(dir / "filenames.txt");
  e = input_error([&] { detect_olat_format(dir); });
  EXPECT_NE(e.find("a DiLiGenT folder needs filenames.txt beside its light_directions.txt"),
            std::string::npos)
      << e;
}

TEST(OlatImport, SaturatedSamplesAreCountedAndOptionallyZeroed) {
  ls::testing::TempDir tmp;
  std::vector<uint16_t> pixels(4 * 4 * 3, 100);
  pixels[0] = 255;  // Pixel (0, 0), red, at the maximum code.
  write_codes(tmp / "a.png", 4, 4, 3, pixels, 8);
  write_codes(tmp / "b.png", 4, 4, 3, std::vector<uint16_t>(4 * 4 * 3, 100), 8);
  write_text(tmp / "s.lp", "2\na.png 0 0 1\nb.png 0 1 1\n");
  OlatImportSummary summary;
  const ReflectanceField kept = import_rti_lp(tmp / "s.lp", {}, &summary);
  EXPECT_EQ(summary.saturated_samples, 1);
  EXPECT_FLOAT_EQ(kept.at(0, 0, 0, 0), 1.0f);  // A lower bound, kept.
  OlatImportOptions options;
  options.zero_saturated = true;
  const ReflectanceField zeroed = import_rti_lp(tmp / "s.lp", options, &summary);
  EXPECT_EQ(zeroed.at(0, 0, 0, 0), 0.0f);
  EXPECT_GT(zeroed.at(0, 0, 0, 1), 0.0f);
}

}  // namespace
}  // namespace ls::capture
