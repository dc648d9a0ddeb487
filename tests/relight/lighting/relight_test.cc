#include "relight/lighting/relight.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "relight/lighting/half_relight.h"
#include "tests/support/test_support.h"

namespace {

using ls::Image;
using ls::capture::FieldLight;
using ls::capture::ReflectanceField;

ReflectanceField random_field(int width, int height, int num_lights, unsigned seed) {
  std::vector<FieldLight> lights(num_lights);
  for (int l = 0; l < num_lights; ++l) lights[l].led_id = l;
  ReflectanceField field(width, height, lights);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> value(0.0f, 2.0f);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      float* p = field.pixel(x, y);
      for (int i = 0; i < 3 * num_lights; ++i) p[i] = value(rng);
    }
  }
  field.source = "random";
  return field;
}

// Sizes include light counts that are not a multiple of the 8-light chunk, and a single light.
TEST(RelightTest, MatchesDoublePrecisionReference) {
  struct Size {
    int width, height, lights;
  };
  for (const Size s : {Size{1, 1, 1}, Size{7, 5, 3}, Size{16, 9, 8}, Size{33, 17, 13},
                       Size{64, 40, 150}, Size{5, 300, 9}, Size{128, 3, 17}}) {
    SCOPED_TRACE(std::to_string(s.width) + "x" + std::to_string(s.height) + "x" +
                 std::to_string(s.lights));
    const ReflectanceField field = random_field(s.width, s.height, s.lights, 100 + s.lights);
    std::mt19937 rng(s.lights);
    std::uniform_real_distribution<float> irradiance(-0.5f, 3.0f);  // Negative lobes too.
    ls::relight::LightWeights weights;
    for (int i = 0; i < 3 * s.lights; ++i) weights.irradiance_rgb.push_back(irradiance(rng));
    const Image out = ls::relight::relight(field, weights);
    ASSERT_EQ(out.width, s.width);
    ASSERT_EQ(out.height, s.height);
    ASSERT_EQ(out.channels, 3);
    int bad = 0;
    for (int y = 0; y < s.height; ++y) {
      for (int x = 0; x < s.width; ++x) {
        for (int c = 0; c < 3; ++c) {
          double expected = 0, magnitude = 0;
          for (int l = 0; l < s.lights; ++l) {
            const double term = double(field.at(x, y, l, c)) * weights.irradiance_rgb[3 * l + c];
            expected += term;
            magnitude += std::abs(term);
          }
          const double tol = 1e-6 * magnitude + 1e-30;
          if (!(std::abs(out.at(x, y, c) - expected) <= tol) && ++bad <= 5) {
            ADD_FAILURE() << "pixel (" << x << ", " << y << ") channel " << c << ": got "
                          << out.at(x, y, c) << ", expected " << expected;
          }
        }
      }
    }
    EXPECT_EQ(bad, 0);
  }
}

TEST(RelightTest, OneHotIrradianceReturnsThatLightsImageExactly) {
  const int lights = 11;
  const ReflectanceField field = random_field(23, 14, lights, 3);
  Image out;
  std::vector<float> e(3 * lights, 0.0f);
  for (int target : {0, 5, 10}) {
    std::fill(e.begin(), e.end(), 0.0f);
    e[3 * target] = e[3 * target + 1] = e[3 * target + 2] = 1.0f;
    ls::relight::relight_into(field, e, out);
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        for (int c = 0; c < 3; ++c) {
          ASSERT_EQ(out.at(x, y, c), field.at(x, y, target, c)) << x << "," << y << "," << c;
        }
      }
    }
  }
  // One channel of one light: only that channel lights up.
  std::fill(e.begin(), e.end(), 0.0f);
  e[3 * 4 + 1] = 1.0f;
  ls::relight::relight_into(field, e, out);
  EXPECT_EQ(out.at(3, 2, 0), 0.0f);
  EXPECT_EQ(out.at(3, 2, 1), field.at(3, 2, 4, 1));
  EXPECT_EQ(out.at(3, 2, 2), 0.0f);
}

TEST(RelightTest, RelightIntoReusesTheCallersImage) {
  const ReflectanceField field = random_field(40, 30, 20, 9);
  std::vector<float> e(60, 0.25f);
  Image out;
  ls::relight::relight_into(field, e, out);
  const float* storage = out.pixels.data();
  const float first = out.at(7, 8, 2);
  e.assign(60, 0.5f);
  ls::relight::relight_into(field, e, out);
  EXPECT_EQ(out.pixels.data(), storage);  // No reallocation across frames.
  EXPECT_FLOAT_EQ(out.at(7, 8, 2), 2 * first);
}

TEST(RelightTest, WeightsForAnotherStageAreAnInputError) {
  const ReflectanceField field = random_field(4, 4, 5, 1);
  ls::relight::LightWeights weights;
  weights.irradiance_rgb.assign(3 * 6, 1.0f);
  try {
    ls::relight::relight(field, weights);
    ADD_FAILURE() << "no InputError";
  } catch (const ls::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("random: lights: the field has 5 lights"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace

// Read from its file as the file holds it (scanline and tiled, in pieces), a field relights to the
// bytes of relight_into on the field in memory: the same sums in the same order.
TEST(RelightTest, RowsAsTheFileHoldsThemRelightToTheSameBytes) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("relight_rows_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const int lights : {1, 8, 13, 151}) {
    // 300 rows of 151 lights are three 8 MiB pieces; 45 columns take each of add_half_plane's
    // loops (32 halves at a time, 8, then one).
    const ReflectanceField field = random_field(45, 300, lights, 7u + unsigned(lights));
    std::vector<float> weights(3 * size_t(lights));
    std::mt19937 rng(lights);
    std::uniform_real_distribution<float> weight(-0.1f, 1.0f);
    for (float& w : weights) w = weight(rng);
    Image in_memory;
    ls::relight::relight_into(field, weights, in_memory);
    for (const int tile : {0, 8}) {
      const std::filesystem::path file = dir / ("field_" + std::to_string(tile) + ".exr");
      ls::capture::write_field(file, field, {}, tile);
      ls::capture::FieldStream stream(file);
      Image from_rows(field.width(), field.height(), 3);
      int pieces = 0;
      stream.read_rows_planar(0, field.height(), [&](const ls::capture::PlanarRows& rows) {
        ls::relight::relight_rows_into(rows, weights, from_rows);
        ++pieces;
      });
      EXPECT_GE(pieces, lights == 151 ? 3 : 1);
      EXPECT_EQ(from_rows.pixels, in_memory.pixels) << lights << " lights, tile " << tile;
    }
    // A half field: its rows summed as the file holds them (converted as they are summed, where
    // the CPU converts halves) give the bytes of the field read back as floats.
    const std::filesystem::path half_file = dir / "half.exr";
    ls::capture::write_field(half_file, field, {}, 0,
                             ls::capture::choose_storage(field, ls::capture::StorageChoice::kHalf));
    Image half_in_memory;
    ls::relight::relight_into(ls::capture::read_field(half_file), weights, half_in_memory);
    ls::capture::FieldStream half_stream(half_file);
    Image half_rows(field.width(), field.height(), 3);
    half_stream.read_rows_planar(0, field.height(), [&](const ls::capture::PlanarRows& rows) {
      EXPECT_EQ(rows.halves != nullptr, ls::capture::cpu_converts_halves());
      ls::relight::relight_rows_into(rows, weights, half_rows);
    });
    EXPECT_EQ(half_rows.pixels, half_in_memory.pixels) << lights << " lights, half";
    EXPECT_NE(half_rows.pixels, in_memory.pixels);  // Half, not float.
    // A NaN among them (in the last row, its 5th value) is found in the sums, and named.
    const std::uint16_t nan = 0x7e00;
    ls::testing::patch_from_end(half_file, size_t(field.width()) * 3 * lights * 2 - 8, &nan, 2);
    ls::capture::FieldStream damaged(half_file);
    try {
      damaged.read_rows_planar(0, field.height(), [&](const ls::capture::PlanarRows& rows) {
        ls::relight::relight_rows_into(rows, weights, half_rows);
      });
      ADD_FAILURE() << "a NaN relit";
    } catch (const ls::InputError& e) {
      EXPECT_THAT(e.what(), ::testing::HasSubstr(half_file.string() + ": the reflectance field "
                                                                      "holds non-finite values"));
    }
  }
  std::filesystem::remove_all(dir);
}

namespace {

// Half floats (the viewer's CPU path): within half's precision of the float relighting, and
// refused when asked for more.
TEST(HalfRelight, MatchesFloatWithinHalfPrecisionOrIsRefused) {
  const ReflectanceField field = random_field(33, 17, 151, 7);
  double error = 0;
  const std::optional<ls::relight::HalfField> half =
      ls::relight::HalfField::of(field, 1e-3, &error);
  if (!half) GTEST_SKIP() << "this CPU has no F16C/AVX2/FMA (error " << error << ")";
  EXPECT_GE(error, 0.0);
  EXPECT_LE(error, 1e-3);
  EXPECT_EQ(half->bytes(), field.values().size() * 2);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> irradiance(0.0f, 3.0f);
  std::vector<float> weights;
  for (int i = 0; i < 3 * field.num_lights(); ++i) weights.push_back(irradiance(rng));
  Image exact, halved;
  ls::relight::relight_into(field, weights, exact);
  half->relight_into(weights, halved);
  ASSERT_EQ(halved.pixels.size(), exact.pixels.size());
  for (size_t i = 0; i < exact.pixels.size(); ++i) {
    // Each value rounds to within 2^-11 of itself: a sum of positive terms too.
    EXPECT_NEAR(halved.pixels[i], exact.pixels[i], 4.9e-4 * exact.pixels[i] + 1e-6) << i;
  }
  weights.pop_back();
  EXPECT_THROW(half->relight_into(weights, halved), ls::InputError);

  // Half rounds each value to 2^-11 of itself: a bound tighter than that refuses it.
  EXPECT_FALSE(ls::relight::HalfField::of(field, 1e-6, &error).has_value());
  EXPECT_GT(error, 1e-6);
}

}  // namespace
