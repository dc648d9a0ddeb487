// The import's check of each image against what the others predict (capture/image_consistency.h),
// on the real sets in ../shared/data: clean sets keep every image; a DiLiGenT set with a fifth of
// its images shifted by 3 px or swapped with another light's has exactly those found, named by
// kind and left out, and its normals stay those of the clean set.
#include "capture/image_consistency.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include "capture/field_file.h"
#include "capture/olat_import.h"
#include "relight/fit/normals.h"
#include "tests/capture/olat_import_sets.h"

namespace ls::capture {
namespace {

using namespace olat_testing;  // NOLINT(google-build-using-namespace)

fs::path diligent(const std::string& object) {
  return ls::testing::shared_data_dir() / "diligent" / object;
}

// A 16-bit image's codes, shifted by (dx, dy) pixels (what moves in at the border is the nearest
// edge pixel's: a camera that moved sees more of the backdrop).
void write_shifted(const fs::path& from, const fs::path& to, int dx, int dy) {
  auto in = OIIO::ImageInput::open(from.string());
  ASSERT_TRUE(in) << from;
  const OIIO::ImageSpec spec = in->spec();
  std::vector<uint16_t> codes(size_t(spec.width) * spec.height * spec.nchannels);
  ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT16, codes.data()));
  std::vector<uint16_t> shifted(codes.size());
  for (int y = 0; y < spec.height; ++y) {
    for (int x = 0; x < spec.width; ++x) {
      const int sx = std::clamp(x - dx, 0, spec.width - 1);
      const int sy = std::clamp(y - dy, 0, spec.height - 1);
      for (int c = 0; c < spec.nchannels; ++c) {
        shifted[(size_t(y) * spec.width + x) * spec.nchannels + c] =
            codes[(size_t(sy) * spec.width + sx) * spec.nchannels + c];
      }
    }
  }
  write_codes(to, spec.width, spec.height, spec.nchannels, shifted, 16);
}

std::vector<std::string> lines_of(const fs::path& file) {
  std::ifstream in(file);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) lines.push_back(line);
  }
  return lines;
}

// Mean angle (degrees) between two normal maps over the pixels both solved.
double mean_angle_deg(const relight::NormalMap& a, const relight::NormalMap& b) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < a.normal.height; ++y) {
    for (int x = 0; x < a.normal.width; ++x) {
      if (a.flags.at(x, y, 0) != 0 || b.flags.at(x, y, 0) != 0) continue;
      double dot = 0;
      for (int c = 0; c < 3; ++c) dot += double(a.normal.at(x, y, c)) * b.normal.at(x, y, c);
      sum += std::acos(std::clamp(dot, -1.0, 1.0)) * kRadToDeg;
      ++n;
    }
  }
  return n > 0 ? sum / n : 180.0;
}

TEST(ImageConsistency, RealSetsKeepEveryImage) {
  const fs::path rti = ls::testing::shared_data_dir() / "rti" / "loewenkopf_klein";
  if (!fs::exists(diligent("ball")) || !fs::exists(rti)) GTEST_SKIP() << "no ../shared/data";
  for (const fs::path& set : {diligent("ball"), diligent("reading"), rti}) {
    OlatImportSummary summary;
    const ReflectanceField field = import_olat(set, {}, &summary);
    std::cout << set.filename() << ": " << summary.consistency << "\n";
    for (const std::string& image : summary.inconsistent) std::cout << "  " << image << "\n";
    EXPECT_TRUE(summary.inconsistent.empty()) << set;
    EXPECT_EQ(field.num_lights(), summary.images) << set;
  }
}

TEST(ImageConsistency, ShiftedAndSwappedImagesAreFoundListedAndLeftOut) {
  if (!fs::exists(diligent("ball"))) GTEST_SKIP() << "no ../shared/data";
  ls::testing::TempDir tmp;
  for (const std::string object : {"ball", "reading"}) {
    const fs::path clean = diligent(object);
    const fs::path glitched = tmp / object;
    fs::create_directories(glitched);
    for (const auto& entry : fs::directory_iterator(clean)) {
      fs::copy(entry.path(), glitched / entry.path().filename());
    }
    std::vector<std::string> names = lines_of(clean / "filenames.txt");
    ASSERT_EQ(names.size(), 96u);
    // A fifth of the 96: ten images shifted by 3 px (in x, in y, diagonally), five pairs of
    // images swapped (each of the ten shows another light's photograph).
    std::map<std::string, ImageProblemKind> expected;
    const int shifted[] = {4, 13, 22, 31, 40, 49, 58, 67, 76, 85};
    for (int i = 0; i < 10; ++i) {
      const int dx = i % 3 == 1 ? 0 : (i % 2 ? -3 : 3), dy = i % 3 == 0 ? 0 : 3;
      const std::string& name = names[size_t(shifted[i])];
      fs::remove(glitched / name);
      write_shifted(clean / name, glitched / name, dx, dy);
      expected[name] = ImageProblemKind::kShifted;
    }
    // Lights 13 to 62 degrees apart: a swap of neighbouring lights (6 degrees, the dome's
    // spacing) is not told from the set's own calibration error (image_consistency.h).
    const std::pair<int, int> swapped[] = {{2, 66}, {9, 70}, {17, 33}, {27, 91}, {61, 80}};
    for (const auto& [a, b] : swapped) {
      std::swap(names[size_t(a)], names[size_t(b)]);
      expected[names[size_t(a)]] = expected[names[size_t(b)]] = ImageProblemKind::kOtherLight;
    }
    std::ostringstream list;
    for (const std::string& name : names) list << name << "\n";
    write_text(glitched / "filenames.txt", list.str());

    OlatImportSummary summary;
    const ReflectanceField field = import_olat(glitched, {}, &summary);
    std::cout << object << ": " << summary.consistency << "\n";
    std::map<std::string, std::string> found;
    for (const std::string& line : summary.inconsistent) {
      std::cout << "  " << line << "\n";
      found[line.substr(0, line.find(' '))] = line;
    }
    EXPECT_EQ(found.size(), expected.size()) << object;
    for (const auto& [name, kind] : expected) {
      ASSERT_TRUE(found.count(name)) << object << ": " << name << " not found";
      // Another light's image, on a smooth object, may also align to its own prediction by a
      // shift and still fit worse than its neighbours: "unlike its light (another light's?)".
      EXPECT_NE(
          found[name].find(kind == ImageProblemKind::kShifted ? ": shifted by" : "another light's"),
          std::string::npos)
          << found[name];
    }
    EXPECT_TRUE(summary.inconsistent_left_out());
    EXPECT_EQ(field.num_lights(), 96 - int(expected.size()));
    // The field holds the others, their ids (file order) kept.
    for (const FieldLight& light : field.lights()) {
      EXPECT_FALSE(expected.count(names[size_t(light.led_id)])) << light.led_id;
    }

    const relight::NormalMap glitched_normals = robust_normals(field);
    const ReflectanceField clean_field = import_olat(clean, {});
    const relight::NormalMap clean_normals = robust_normals(clean_field);
    // The clean set without the same lights: what leaving them out costs by itself.
    std::vector<int> same_lights;
    for (const FieldLight& light : field.lights()) same_lights.push_back(light.led_id);
    const relight::NormalMap fewer_normals =
        robust_normals(select_lights(clean_field, same_lights));
    OlatImportOptions keep_all;
    keep_all.keep_all = true;
    const relight::NormalMap kept_normals = robust_normals(import_olat(glitched, keep_all));
    const double left_out = mean_angle_deg(glitched_normals, clean_normals);
    const double as_without = mean_angle_deg(glitched_normals, fewer_normals);
    const double kept = mean_angle_deg(kept_normals, clean_normals);
    std::cout << object << ": normals " << left_out << " deg from the clean set's with the "
              << "glitched images left out (" << as_without << " deg from the clean set without "
              << "the same images), " << kept << " deg with them kept\n";
    // Measured: ball 0.143 (0.006), kept 0.243; reading 1.252 (0.006), kept 2.610. What is left
    // is the cost of 76 lights instead of 96: the images left out are exactly the glitched ones.
    EXPECT_LT(as_without, 0.05);  // A guard over the measured 0.006.
    if (object == "ball") {
      EXPECT_LT(left_out, 0.2);  // Issue 49's bound.
    }
    EXPECT_GT(kept, left_out);  // Control: keeping the glitches costs more than leaving them out.
  }
}

// A copy of the shared ball whose image 052.png, its most frontal light's, is black.
void copy_ball_with_a_black_image(const fs::path& set) {
  fs::copy(diligent("ball"), set);
  auto in = OIIO::ImageInput::open((set / "052.png").string());
  ASSERT_TRUE(in);
  const OIIO::ImageSpec spec = in->spec();
  in.reset();
  fs::remove(set / "052.png");
  write_codes(set / "052.png", spec.width, spec.height, spec.nchannels,
              std::vector<uint16_t>(size_t(spec.width) * spec.height * spec.nchannels, 0), 16);
}

// On the command line: a black image among a real set's is named with its reason on stderr and
// left out (the preview shows the most frontal light kept); --keep-all keeps it.
TEST(ImageConsistency, CliListsABlackImageAndKeepAllKeepsIt) {
  if (!fs::exists(diligent("ball"))) GTEST_SKIP() << "no ../shared/data";
  ls::testing::TempDir tmp;
  const fs::path set = tmp / "ball";
  copy_ball_with_a_black_image(set);
  const std::string cli = ls::testing::cli_path().string();
  std::string output;
  int rc = ls::testing::run_command(
      cli + " import '" + set.string() + "' --quiet --out '" + (tmp / "f.exr").string() + "'",
      &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_NE(output.find("96 images checked against what the others predict: 1 left out"),
            std::string::npos)
      << output;
  EXPECT_NE(output.find("warning: left out 052.png"), std::string::npos) << output;
  EXPECT_NE(output.find("black"), std::string::npos) << output;
  EXPECT_EQ(read_field(tmp / "f.exr").num_lights(), 95);
  EXPECT_EQ(output.find("(light 51)"), std::string::npos) << output;
  const Image preview = read_image(tmp / "f.preview.png");
  double sum = 0;
  for (float v : preview.pixels) sum += v;
  EXPECT_GT(sum / double(preview.pixels.size()), 0.01);  // Not the black image.

  rc = ls::testing::run_command(cli + " import '" + set.string() + "' --quiet --keep-all --out '" +
                                    (tmp / "all.exr").string() + "'",
                                &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_NE(output.find("not checked (--keep-all)"), std::string::npos) << output;
  EXPECT_EQ(read_field(tmp / "all.exr").num_lights(), 96);
}

// A time-lapse's steps are fitted over the same lights: an inconsistent image in one step is
// listed, and kept, so that every step keeps every light.
TEST(ImageConsistency, ATimeLapseListsAnInconsistentImageAndKeepsIt) {
  if (!fs::exists(diligent("ball"))) GTEST_SKIP() << "no ../shared/data";
  ls::testing::TempDir tmp;
  fs::create_directories(tmp / "steps");
  fs::copy(diligent("ball"), tmp / "steps" / "a");
  copy_ball_with_a_black_image(tmp / "steps" / "b");
  std::string output;
  const int rc = ls::testing::run_command(
      ls::testing::cli_path().string() + " import '" + (tmp / "steps").string() +
          "' --interval 60 --quiet --out '" + (tmp / "lapse").string() + "'",
      &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_NE(output.find("warning: kept 052.png"), std::string::npos) << output;
  EXPECT_NE(output.find("1 kept"), std::string::npos) << output;
  EXPECT_EQ(read_field(tmp / "lapse" / "field_t000.exr").num_lights(), 96);
  EXPECT_EQ(read_field(tmp / "lapse" / "field_t001.exr").num_lights(), 96);
}

}  // namespace
}  // namespace ls::capture
