// A field opened at a reduced resolution (capture/reduced_field.h): block means of the file's
// pixels, read in bands of scanline and tiled files alike.
#include "capture/reduced_field.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "tests/support/test_support.h"

namespace ls::capture {
namespace {

ReflectanceField reduced_test_field(int width, int height, int num_lights) {
  std::vector<FieldLight> lights;
  for (int l = 0; l < num_lights; ++l) {
    lights.push_back(FieldLight{l + 1, Eigen::Vector3d(0.1 * l, 1, 0.3).normalized(), true});
  }
  ReflectanceField field(width, height, lights);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> value(0.0f, 2.0f);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int i = 0; i < 3 * num_lights; ++i) field.pixel(x, y)[i] = value(rng);
    }
  }
  field.noise = {1e-4, 2e-3, true, "test"};
  return field;
}

TEST(ReducedField, EachPixelIsTheMeanOfItsBlockInEveryLayout) {
  const ls::testing::TempDir dir;
  // 37 x 29: the last block column holds 1 pixel, the last block row 1 row.
  const ReflectanceField field = reduced_test_field(37, 29, 5);
  write_field(dir / "scanline.exr", field);
  write_field(dir / "tiled.exr", field, {}, 16);
  constexpr int kFactor = 4;
  std::vector<float> expected;
  for (int by = 0; by < 8; ++by) {
    for (int bx = 0; bx < 10; ++bx) {
      for (int i = 0; i < 15; ++i) {
        double sum = 0;
        int n = 0;
        for (int y = by * kFactor; y < std::min(29, (by + 1) * kFactor); ++y) {
          for (int x = bx * kFactor; x < std::min(37, (bx + 1) * kFactor); ++x) {
            sum += field.pixel(x, y)[i], ++n;
          }
        }
        expected.push_back(float(sum / n));
      }
    }
  }
  for (const char* name : {"scanline.exr", "tiled.exr"}) {
    FieldStream stream(dir / name);
    int bands = 0;
    // A band of one block of rows (16 for the tiled file) at a time.
    const ReflectanceField reduced = read_reduced_field(
        stream, kFactor, 1, [&](const std::string&, long, long, const std::string&) { ++bands; });
    EXPECT_EQ(reduced.width(), 10) << name;
    EXPECT_EQ(reduced.height(), 8) << name;
    EXPECT_GT(bands, 1) << name;
    EXPECT_EQ(reduced.values(), expected) << name;
    // The mean of 16 pixels' values: a sixteenth of their variance.
    EXPECT_DOUBLE_EQ(reduced.noise.read_variance, 1e-4 / 16) << name;
    EXPECT_DOUBLE_EQ(reduced.noise.shot_variance_per_unit, 2e-3 / 16) << name;
    EXPECT_EQ(reduced.num_lights(), 5) << name;
  }
}

TEST(ReducedField, TheFactorIsTheSmallestPowerOfTwoThatFits) {
  // The built-in dome at 4096² (151 LEDs, 30 GB of floats) in 2 GiB: a quarter on each side.
  EXPECT_EQ(reduction_factor(4096, 4096, 151, std::size_t(2) << 30), 4);
  EXPECT_EQ(reduction_factor(512, 512, 151, std::size_t(2) << 30), 1);
  EXPECT_EQ(reduction_factor(6000, 4000, 346, std::size_t(1) << 30), 16);
}

}  // namespace
}  // namespace ls::capture
