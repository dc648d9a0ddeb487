// The DiLiGenT importer on sets written from the simulator (normals and colours against its ground
// truth), and imports in bands within a memory budget, resumed after a kill.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <iostream>
#include <mutex>

#include "capture/field_file.h"
#include "capture/olat_import.h"
#include "tests/capture/olat_import_sets.h"

namespace ls::capture {
namespace {

using namespace olat_testing;  // NOLINT(google-build-using-namespace)

// --- DiLiGenT layout from the simulator
// -----------------------------------------------------------

TEST(OlatImport, DiligentFromSimMatchesGroundTruthNormalsAndColours) {
  ls::testing::TempDir tmp;
  const SimSet set = render_sphere(40, 60);
  write_diligent(set, tmp / "sphere", 5);

  OlatImportSummary summary;
  const ReflectanceField field = import_olat(tmp / "sphere", {}, &summary);
  EXPECT_EQ(summary.format, OlatFormat::kDiligent);
  ASSERT_EQ(field.num_lights(), 60);
  EXPECT_TRUE(summary.intensities_divided);
  EXPECT_EQ(summary.transfer_undone, "none (linear)");
  EXPECT_EQ(summary.pixel_format, "16-bit RGB");
  EXPECT_EQ(summary.saturated_samples, 0);
  expect_finite_nonnegative(field);
  int background = 0;
  for (const sim::SurfaceHit& h : set.hits) background += !h.hit;
  EXPECT_EQ(summary.masked_out_pixels, background);

  const relight::NormalMap map = robust_normals(field);
  const NormalError e = normal_error(map, set);
  const Eigen::Vector3d ratio = median_albedo_ratio(map);
  std::cout << "DiLiGenT layout: mean angular error " << e.mean_deg << " deg over " << e.pixels
            << " pixels, " << e.flagged << " object pixels flagged; albedo R/G " << ratio.x()
            << " B/G " << ratio.z() << " (truth 1.4, 0.6)\n";
  // Measured: 0.059 deg, 0 of 912 object pixels flagged; R/G 1.40004, B/G 0.59999 (seed 5).
  EXPECT_LT(e.mean_deg, 0.3);
  EXPECT_LE(e.flagged, e.pixels / 50);
  EXPECT_NEAR(ratio.x(), 1.4, 0.005);
  EXPECT_NEAR(ratio.z(), 0.6, 0.005);
  // Outside the mask: zero samples, marked as having no signal (never NaN), and counted apart
  // from the flagged pixels (summaries aware of the mask).
  for (const sim::SurfaceHit& h : set.hits) {
    if (h.hit) continue;
    EXPECT_EQ(field.at(h.pixel_x, h.pixel_y, 0, 0), 0.0f);
    EXPECT_EQ(int(map.flags.at(h.pixel_x, h.pixel_y, 0)), relight::kNoSignal);
  }
  EXPECT_EQ(map.empty_pixels, background);
  EXPECT_EQ(map.flagged_pixels, e.flagged);

  // Control: the same images without their intensities change the colours measurably.
  fs::remove(tmp / "sphere/light_intensities.txt");
  OlatImportSummary undivided_summary;
  const ReflectanceField undivided = import_diligent(tmp / "sphere", {}, &undivided_summary);
  // Said as a warning, with what was assumed; nothing claims the intensities were divided out.
  ASSERT_EQ(undivided_summary.warnings.size(), 1u);
  EXPECT_NE(undivided_summary.warnings[0].find(
                "light_intensities.txt: not found; every light taken as intensity 1"),
            std::string::npos)
      << undivided_summary.warnings[0];
  EXPECT_FALSE(undivided_summary.intensities_divided);
  const Eigen::Vector3d wrong = median_albedo_ratio(robust_normals(undivided));
  std::cout << "without light_intensities.txt: albedo R/G " << wrong.x() << " B/G " << wrong.z()
            << "\n";
  // Measured: R/G 0.91, B/G 0.79 (the intensities' channel means are 0.75, 1.2, 1.5).
  EXPECT_GT(std::abs(wrong.x() - 1.4), 0.2);
}

TEST(OlatImport, DiligentDownsizedKeepsMaskBorderUndarkened) {
  ls::testing::TempDir tmp;
  const SimSet set = render_sphere(40, 40);
  write_diligent(set, tmp / "sphere", 9);
  OlatImportOptions options;
  options.max_size = 20;
  const ReflectanceField field = import_diligent(tmp / "sphere", options);
  ASSERT_EQ(field.width(), 20);
  expect_finite_nonnegative(field);
  const relight::NormalMap map = robust_normals(field);
  const NormalError e = normal_error(map, set, /*downsample=*/2);
  const Eigen::Vector3d ratio = median_albedo_ratio(map);
  std::cout << "DiLiGenT layout at half size: mean angular error " << e.mean_deg << " deg over "
            << e.pixels << " pixels, " << e.flagged << " flagged; R/G " << ratio.x() << "\n";
  // Measured: 0.25 deg over 226 pixels, 2 flagged (the block's mean normal is not exactly the
  // normal of its mean shading); R/G 1.40004.
  EXPECT_LT(e.mean_deg, 1.0);
  EXPECT_LE(e.flagged, e.pixels / 20);
  EXPECT_NEAR(ratio.x(), 1.4, 0.005);
}

// Imported in bands of rows through a spill file (a set larger than memory), the field
// file holds the values and lights of the import in memory, and each light's image is seen once.
TEST(OlatImport, InBandsWithinAMemoryBudgetWritesTheFieldOfTheWholeImport) {
  ls::testing::TempDir tmp;
  const SimSet set = render_sphere(40, 24);
  write_diligent(set, tmp / "sphere", 9);  // A mask, RGB intensities to divide out.
  OlatImportOptions options;
  options.max_size = 30;  // Area-averaged to 30 x 30.
  const ReflectanceField whole = import_diligent(tmp / "sphere", options);
  std::vector<int> seen(24, 0);
  std::mutex mutex;
  const auto count = [&](int light, const Eigen::Vector3d& dir, const std::vector<float>& rgb) {
    const std::lock_guard lock(mutex);
    ++seen[size_t(light)];
    EXPECT_EQ(dir, whole.lights()[size_t(light)].dir_in_stage);
    EXPECT_EQ(rgb.size(), size_t(30 * 30 * 3));
    EXPECT_EQ(rgb[3 * (15 * 30 + 15) + 1], whole.at(15, 15, light, 1));
  };
  const MemoryBudget budget(2 * ReflectanceField::bytes_for(30, 4, 24));  // Bands of 4 rows.
  OlatImportSummary summary;
  EXPECT_EQ(
      import_olat_to_file(tmp / "sphere", options, tmp / "bands.exr", {}, budget, count, &summary),
      4);
  EXPECT_EQ(seen, std::vector<int>(24, 1));
  EXPECT_EQ(summary.width, 30);
  const ReflectanceField banded = read_field(tmp / "bands.exr");
  EXPECT_TRUE(banded.values() == whole.values());  // Bit for bit.
  ASSERT_EQ(banded.num_lights(), whole.num_lights());
  for (int l = 0; l < whole.num_lights(); ++l) {
    EXPECT_EQ(banded.lights()[l].saturates_at, whole.lights()[l].saturates_at);
  }
  std::vector<std::string> left;
  for (const auto& entry : fs::directory_iterator(tmp.path())) {
    left.push_back(entry.path().filename().string());
  }
  EXPECT_THAT(left, ::testing::UnorderedElementsAre("sphere", "bands.exr"));
}

// An import in bands stopped halfway through reading the images (as by a kill) resumes
// from the images it read (kept in OUT.partial/ with a record each): it reads only the rest, and
// writes the field and the lights' ceilings of an uninterrupted import.
TEST(OlatImport, AKilledImportInBandsResumesFromTheImagesItRead) {
  ls::testing::TempDir tmp;
  const SimSet set = render_sphere(40, 24);
  write_diligent(set, tmp / "sphere", 9);
  OlatImportOptions options;
  const ReflectanceField whole = import_diligent(tmp / "sphere", options);
  const MemoryBudget budget(2 * ReflectanceField::bytes_for(40, 4, 24));  // Bands of 4 rows.
  struct Killed {};
  OlatImportOptions killed = options;
  killed.progress = [](const std::string&, long done, long total, const std::string&) {
    if (2 * done >= total) throw Killed{};
  };
  EXPECT_THROW((void)import_olat_to_file(tmp / "sphere", killed, tmp / "bands.exr", {}, budget),
               Killed);
  EXPECT_FALSE(fs::exists(tmp / "bands.exr"));
  ASSERT_TRUE(fs::exists(tmp / "bands.exr.partial" / "lights.spill"));
  OlatImportSummary summary;
  std::vector<int> seen(24, 0);
  std::mutex mutex;
  const auto count = [&](int light, const Eigen::Vector3d&, const std::vector<float>&) {
    const std::lock_guard lock(mutex);
    ++seen[size_t(light)];
  };
  (void)import_olat_to_file(tmp / "sphere", options, tmp / "bands.exr", {}, budget, count,
                            &summary);
  EXPECT_GE(2 * summary.resumed_lights, 24);
  EXPECT_LT(summary.resumed_lights, 24);
  EXPECT_EQ(seen, std::vector<int>(24, 1)) << "kept images are seen too (the preview)";
  const ReflectanceField banded = read_field(tmp / "bands.exr");
  EXPECT_TRUE(banded.values() == whole.values());
  for (int l = 0; l < whole.num_lights(); ++l) {
    EXPECT_EQ(banded.lights()[l].saturates_at, whole.lights()[l].saturates_at);
  }
  EXPECT_FALSE(fs::exists(tmp / "bands.exr.partial"));
}

}  // namespace
}  // namespace ls::capture
