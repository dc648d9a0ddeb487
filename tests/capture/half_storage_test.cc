// Half-float field files: half the bytes, values within half's precision of the floats,
// the choice recorded in the file and refused where the field relit from halves would be off by
// more than kHalfRelitTolerance.
#include "capture/half_storage.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>

#include "capture/band_spill.h"
#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "tests/support/test_support.h"

namespace ls::capture {
namespace {

using ::testing::HasSubstr;

// Radiance-like values (log-normal: median e^-3, spread e^log_spread), as a dome's one-light
// images hold: lit and shadowed, matte and glossy.
ReflectanceField radiance_field(int width, int height, int num_lights, std::uint64_t seed,
                                float log_spread = 2.0f) {
  std::vector<FieldLight> lights;
  for (int l = 0; l < num_lights; ++l) {
    lights.push_back(FieldLight{l + 1, Eigen::Vector3d(0.1 * l, 1, 0.3).normalized(), true});
  }
  ReflectanceField field(width, height, lights);
  std::mt19937_64 rng(seed);
  std::lognormal_distribution<float> value(-3.0f, log_spread);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int i = 0; i < 3 * num_lights; ++i) field.pixel(x, y)[i] = value(rng);
    }
  }
  return field;
}

// Per pixel and colour, the sum over lights (a relighting under equal weights).
std::vector<double> relit(const ReflectanceField& field) {
  std::vector<double> sums;
  for (int y = 0; y < field.height(); ++y) {
    for (int x = 0; x < field.width(); ++x) {
      for (int c = 0; c < 3; ++c) {
        double sum = 0;
        for (int l = 0; l < field.num_lights(); ++l) sum += field.at(x, y, l, c);
        sums.push_back(sum);
      }
    }
  }
  return sums;
}

TEST(HalfStorage, HalvesTheFileAndReadsBackWithinHalfPrecision) {
  ls::testing::TempDir dir;
  const ReflectanceField field = radiance_field(33, 21, 40, 1);
  HalfCheck check;
  const FieldStorage storage = choose_storage(field, StorageChoice::kAuto, &check);
  ASSERT_TRUE(storage.half) << check.describe();
  EXPECT_LE(check.relit_error, kHalfRelitTolerance);
  EXPECT_EQ(check.noise_ratio, -1);  // No measured noise to hold it against.
  write_field(dir / "float.exr", field);
  write_field(dir / "half.exr", field, {}, 0, storage);
  write_field(dir / "half_tiled.exr", field, {}, 16, storage);  // Read through OpenEXR.
  const double ratio = double(std::filesystem::file_size(dir / "half.exr")) /
                       double(std::filesystem::file_size(dir / "float.exr"));
  EXPECT_NEAR(ratio, 0.5, 0.02);

  FieldStream stream(dir / "half.exr");
  EXPECT_TRUE(stream.storage().half);
  EXPECT_EQ(stream.storage().scale, storage.scale);
  EXPECT_FALSE(FieldStream(dir / "float.exr").storage().half);
  const ReflectanceField back = read_field(dir / "half.exr");
  // Half keeps 11 significant bits: |error| <= 2^-11 |v| in its normal range (above 2^-14 once
  // scaled), at most half its smallest step (2^-25 / scale) below it.
  const float floor = std::ldexp(1.0f, -25) / storage.scale;
  for (std::size_t i = 0; i < field.values().size(); ++i) {
    const float v = field.values()[i];
    ASSERT_LE(std::abs(back.values()[i] - v), std::ldexp(std::abs(v), -11) + floor) << i;
  }
  // Raw rows (scanlines) and OpenEXR's conversion (tiles) give the same floats.
  const ReflectanceField tiled = read_field(dir / "half_tiled.exr");
  EXPECT_EQ(tiled.values(), back.values());
  // Relit, within the tolerance the choice was made with (on every pixel, not only its sample).
  const std::vector<double> exact = relit(field), from_half = relit(back);
  double worst = 0;
  for (std::size_t i = 0; i < exact.size(); ++i) {
    worst = std::max(worst, std::abs(from_half[i] - exact[i]) / exact[i]);
  }
  EXPECT_LE(worst, kHalfRelitTolerance);
  EXPECT_GT(worst, 0);  // Half, not float after all.
}

TEST(HalfStorage, AutoKeepsFloatWhereHalfsRoundingIsNotWellBelowTheNoise) {
  // Values up to about 10, the simulated camera's noise (a 12-bit sensor's read noise, and a full
  // well that 1.0 nearly fills: shot sigma 0.007 there); half's rounding stays a fraction of it
  // (at v: 2^-12 v against sqrt(5e-5 v), 0.1 sigma at v = 10).
  ReflectanceField field = radiance_field(16, 16, 8, 2, 1.2f);
  field.noise = {.read_variance = 2.5e-8, .shot_variance_per_unit = 5e-5, .measured = true};
  HalfCheck check;
  EXPECT_TRUE(choose_storage(field, StorageChoice::kAuto, &check).half) << check.describe();
  EXPECT_LT(check.noise_ratio, kHalfNoiseTolerance);
  // A field measured with a thousand times less noise than half's rounding (a deep HDR merge of
  // many exposures): float, and the check says why.
  field.noise = {.read_variance = 1e-20, .shot_variance_per_unit = 1e-14, .measured = true};
  EXPECT_FALSE(choose_storage(field, StorageChoice::kAuto, &check).half);
  EXPECT_GT(check.noise_ratio, kHalfNoiseTolerance);
  EXPECT_LE(check.relit_error, kHalfRelitTolerance);  // Its relit error alone would allow it.
  EXPECT_THAT(check.describe(), HasSubstr("sigma of the noise"));
  EXPECT_TRUE(choose_storage(field, StorageChoice::kHalf).half);  // Asked for: given.
  EXPECT_FALSE(choose_storage(field, StorageChoice::kFloat).half);
}

// A NaN among the halves is refused when the rows are converted (rows left in place for a
// consumer that converts as it sums are checked by it: RelightTest).
TEST(HalfStorage, ANonFiniteHalfIsRefusedByName) {
  ls::testing::TempDir dir;
  const ReflectanceField field = radiance_field(16, 9, 3, 4);
  const std::filesystem::path path = dir / "half.exr";
  write_field(path, field, {}, 0, choose_storage(field, StorageChoice::kHalf));
  // A NaN in row 6 of 9 (16 pixels x 9 channels of halves a row, after the chunk's 8 bytes).
  const std::uint16_t nan = 0x7e00;
  ls::testing::patch_from_end(path, 3 * (8 + 16 * 9 * 2) - 8 - 10, &nan, 2);
  const auto error = [&](const std::function<void()>& read) {
    try {
      read();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("read");
  };
  EXPECT_THAT(error([&] { read_field(path); }),
              HasSubstr(path.string() + ": the reflectance field holds non-finite values"));
  // Row 4 of 9 claiming to be row 5: refused naming the row, as rows for a consumer that sums the
  // halves as stored too (each chunk checked as it is read).
  const std::filesystem::path moved = dir / "moved.exr";
  write_field(moved, field, {}, 0, choose_storage(field, StorageChoice::kHalf));
  const std::int32_t wrong_row = 5;
  ls::testing::patch_from_end(moved, 5 * (8 + 16 * 9 * 2), &wrong_row, 4);
  const std::string planar = error([&] {
    FieldStream stream(moved);
    stream.read_rows_planar(0, stream.height(), [](const PlanarRows&) {});
  });
  EXPECT_THAT(planar, HasSubstr(moved.string() + ": row 4"));
}

// Built in bands through a spill (a field larger than memory), the same choice as in memory: the
// bands carry the field's measured noise to the check.
TEST(HalfStorage, BandsThroughASpillAreCheckedAgainstTheFieldsNoise) {
  ls::testing::TempDir dir;
  ReflectanceField field = radiance_field(16, 12, 4, 5, 1.2f);
  for (const double read_variance : {2.5e-8, 1e-20}) {  // The camera's; far below half's rounding.
    field.noise = {.read_variance = read_variance,
                   .shot_variance_per_unit = read_variance * 2e3,
                   .measured = true};
    SpillFile spill(dir / "field.exr", 16, 12, 4, /*band_rows=*/5);
    for (int l = 0; l < 4; ++l) {
      std::vector<float> rgb(16 * 12 * 3);
      for (int y = 0; y < 12; ++y) {
        for (int x = 0; x < 16; ++x) {
          for (int c = 0; c < 3; ++c) rgb[size_t((y * 16 + x) * 3 + c)] = field.at(x, y, l, c);
        }
      }
      spill.put(l, rgb);
    }
    ReflectanceField header = ReflectanceField::without_values(16, 12, field.lights());
    header.noise = field.noise;
    HalfCheck check;
    const FieldStorage banded =
        spill.write_field(dir / "field.exr", header, {}, {}, StorageChoice::kAuto, &check);
    EXPECT_EQ(banded.half, choose_storage(field, StorageChoice::kAuto).half) << read_variance;
    EXPECT_EQ(banded.half, read_variance > 1e-10) << check.describe();
    EXPECT_EQ(FieldStream(dir / "field.exr").storage().half, banded.half);
  }
}

TEST(HalfStorage, AStorageAttributeThatIsNotOneIsRefusedByName) {
  EXPECT_EQ(FieldStorage::parse("f.exr", R"({"values": "half", "scale": 0.125})").scale, 0.125f);
  const auto error = [](const std::string& json) {
    try {
      FieldStorage::parse("f.exr", json);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("parsed");
  };
  EXPECT_THAT(error(R"({"values": "half", "scale": 3})"),
              HasSubstr("f.exr: attribute 'lightstage:storage': scale: expected a power of two"));
  EXPECT_THAT(error(R"({"values": "int8", "scale": 1})"), HasSubstr("values: expected"));
  EXPECT_THAT(error(R"({"values": "half"})"), HasSubstr("lightstage:storage"));
  EXPECT_THAT(error("not json"), HasSubstr("f.exr"));
}

}  // namespace
}  // namespace ls::capture
