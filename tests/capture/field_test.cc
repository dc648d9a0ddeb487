#include "capture/field.h"

#include <OpenImageIO/imageio.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>

#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "tests/support/test_support.h"

namespace ls::capture {
namespace {

using ::testing::HasSubstr;

std::vector<FieldLight> make_lights(int n) {
  std::vector<FieldLight> lights;
  for (int l = 0; l < n; ++l) {
    const double a = 0.3 * l;
    // Ids out of order and with gaps, as a capture order may be.
    lights.push_back(FieldLight{(l * 37) % 211 + 1,
                                Eigen::Vector3d(std::sin(a), 0.6, std::cos(a)).normalized(),
                                l % 5 != 3});
    // Every other light has a saturation ceiling; the rest never saturate (no key in the file,
    // as in files written before the key existed).
    if (l % 2 == 0) lights.back().saturates_at = Eigen::Vector3f(1.5f, 2.25f, 3.0f + 0.1f * l);
  }
  return lights;
}

ReflectanceField random_field(int width, int height, int num_lights, uint64_t seed) {
  ReflectanceField field(width, height, make_lights(num_lights));
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> value(0.2f, 0.3f);  // Includes negatives (noise below dark).
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      float* p = field.pixel(x, y);
      for (int i = 0; i < 3 * num_lights; ++i) p[i] = value(rng);
    }
  }
  field.scene_time_s = 12.345678901234;
  field.noise = {.read_variance = 1.25e-7,
                 .shot_variance_per_unit = 3.5e-5,
                 .measured = true,
                 .method = "test"};
  return field;
}

void expect_same(const ReflectanceField& a, const ReflectanceField& b) {
  ASSERT_EQ(a.width(), b.width());
  ASSERT_EQ(a.height(), b.height());
  ASSERT_EQ(a.num_lights(), b.num_lights());
  for (int l = 0; l < a.num_lights(); ++l) {
    EXPECT_EQ(a.lights()[l].led_id, b.lights()[l].led_id);
    EXPECT_EQ(a.lights()[l].valid, b.lights()[l].valid);
    EXPECT_EQ(a.lights()[l].dir_in_stage,
              b.lights()[l].dir_in_stage);  // Exact: JSON round-trips doubles.
    EXPECT_EQ(a.lights()[l].saturates_at, b.lights()[l].saturates_at);  // Infinity included.
  }
  EXPECT_EQ(a.scene_time_s, b.scene_time_s);
  EXPECT_EQ(a.noise.measured, b.noise.measured);
  EXPECT_EQ(a.noise.read_variance, b.noise.read_variance);
  EXPECT_EQ(a.noise.shot_variance_per_unit, b.noise.shot_variance_per_unit);
  EXPECT_EQ(a.noise.method, b.noise.method);
  ASSERT_EQ(a.values().size(), b.values().size());
  EXPECT_EQ(0, std::memcmp(a.values().data(), b.values().data(), a.bytes())) << "not bit-exact";
}

TEST(Field, LayoutIsPixelMajorLightMajorRgbInnermost) {
  ReflectanceField field(4, 3, make_lights(5));
  EXPECT_EQ(field.bytes(), ReflectanceField::bytes_for(4, 3, 5));
  field.at(2, 1, 3, 1) = 7.0f;
  EXPECT_EQ(field.values()[((1 * 4 + 2) * 5 + 3) * 3 + 1], 7.0f);
  EXPECT_EQ(field.at(0, 0, 0, 0), 0.0f);  // Zero-initialised.
}

TEST(Field, RoundTripIsBitExactWithMetadata) {
  ls::testing::TempDir dir;
  const ReflectanceField field = random_field(37, 23, 11, 1);
  write_field(dir / "field.exr", field);
  EXPECT_FALSE(std::filesystem::exists(dir / "field.exr.tmp"));
  const ReflectanceField back = read_field(dir / "field.exr");
  expect_same(field, back);
  EXPECT_EQ(back.source, (dir / "field.exr").string());
  // Rewriting over an existing file replaces it.
  const ReflectanceField other = random_field(37, 23, 11, 2);
  write_field(dir / "field.exr", other);
  expect_same(other, read_field(dir / "field.exr"));
  // Only the field remains: no temporary files left behind.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
}

TEST(Field, ShuffledChannelOrderOnDiskReadsRight) {
  ls::testing::TempDir dir;
  const int width = 9, height = 7, num_lights = 6;
  ReflectanceField field = random_field(width, height, num_lights, 3);
  field.noise = {};  // Written by hand below without a noise attribute: read back as unmeasured.
  // Nor with saturation ceilings, as files written before they existed: read back as "never".
  for (FieldLight& l : field.lights()) {
    l.saturates_at.setConstant(std::numeric_limits<float>::infinity());
  }
  // Write the same field with its channels in a random order, by hand.
  const int nch = 3 * num_lights;
  std::vector<int> order(nch);
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), std::mt19937(5));
  OIIO::ImageSpec spec(width, height, nch, OIIO::TypeDesc::FLOAT);
  spec.channelnames.clear();
  const char rgb[] = "RGB";
  nlohmann::json lights = nlohmann::json::array();
  for (const FieldLight& l : field.lights()) {
    lights.push_back({{"id", l.led_id},
                      {"dir", {l.dir_in_stage.x(), l.dir_in_stage.y(), l.dir_in_stage.z()}},
                      {"valid", l.valid}});
  }
  for (int i : order) {
    char name[32];
    std::snprintf(name, sizeof(name), "led%03d.%c", field.lights()[i / 3].led_id, rgb[i % 3]);
    spec.channelnames.push_back(name);
  }
  spec.attribute("lightstage:lights", lights.dump());
  spec.attribute("lightstage:scene_time_s", OIIO::TypeDesc::DOUBLE, &field.scene_time_s);
  std::vector<float> shuffled(size_t(width) * height * nch);
  for (size_t p = 0; p < size_t(width) * height; ++p) {
    for (int i = 0; i < nch; ++i) shuffled[p * nch + i] = field.values()[p * nch + order[i]];
  }
  const std::string path = (dir / "shuffled.exr").string();
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out && out->open(path, spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, shuffled.data()));
  ASSERT_TRUE(out->close());
  expect_same(field, read_field(path));
}

// Writes an EXR with the given channel names and optional lights attribute.
void write_plain_exr(const std::string& path, const std::vector<std::string>& names,
                     const std::string& lights_json) {
  OIIO::ImageSpec spec(2, 2, int(names.size()), OIIO::TypeDesc::FLOAT);
  spec.channelnames = names;
  if (!lights_json.empty()) spec.attribute("lightstage:lights", lights_json);
  std::vector<float> data(4 * names.size(), 1.0f);
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out && out->open(path, spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, data.data()));
  ASSERT_TRUE(out->close());
}

std::string read_error(const std::filesystem::path& path) {
  try {
    read_field(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// A one-light field file whose scene time attribute has the given type and value.
template <class T>
void write_timed_exr(const std::string& path, OIIO::TypeDesc type, T time) {
  OIIO::ImageSpec spec(2, 2, 3, OIIO::TypeDesc::FLOAT);
  spec.channelnames = {"led004.R", "led004.G", "led004.B"};
  spec.attribute("lightstage:lights", R"([{"id": 4, "dir": [0, 1, 0], "valid": true}])");
  spec.attribute("lightstage:scene_time_s", type, &time);
  std::vector<float> data(12, 1.0f);
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out && out->open(path, spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, data.data()));
  ASSERT_TRUE(out->close());
}

TEST(Field, SceneTimeOfAnyNumericTypeIsReadNeverTakenAsZero) {
  ls::testing::TempDir dir;
  const std::string as_int = (dir / "int.exr").string();
  write_timed_exr(as_int, OIIO::TypeDesc::INT, 3600);
  EXPECT_EQ(read_field(as_int).scene_time_s, 3600.0);
  const std::string as_float = (dir / "float.exr").string();
  write_timed_exr(as_float, OIIO::TypeDesc::FLOAT, 12.5f);
  EXPECT_EQ(read_field(as_float).scene_time_s, 12.5);
  const std::string as_double = (dir / "double.exr").string();
  write_timed_exr(as_double, OIIO::TypeDesc::DOUBLE, 86400.25);
  EXPECT_EQ(read_field(as_double).scene_time_s, 86400.25);
  const std::string as_text = (dir / "text.exr").string();
  {
    OIIO::ImageSpec spec(2, 2, 3, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"led004.R", "led004.G", "led004.B"};
    spec.attribute("lightstage:lights", R"([{"id": 4, "dir": [0, 1, 0], "valid": true}])");
    spec.attribute("lightstage:scene_time_s", "noon");
    std::vector<float> data(12, 1.0f);
    auto out = OIIO::ImageOutput::create(as_text);
    ASSERT_TRUE(out && out->open(as_text, spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, data.data()));
    ASSERT_TRUE(out->close());
  }
  EXPECT_THAT(read_error(as_text), HasSubstr("text.exr: attribute 'lightstage:scene_time_s': "
                                             "expected a finite number of seconds, got string"));
  const std::string as_nan = (dir / "nan.exr").string();
  write_timed_exr(as_nan, OIIO::TypeDesc::DOUBLE, std::nan(""));
  EXPECT_THAT(read_error(as_nan), HasSubstr("nan.exr: attribute 'lightstage:scene_time_s'"));
}

TEST(Field, ReadValidatesAndNamesTheFile) {
  ls::testing::TempDir dir;
  const std::string one_light = R"([{"id": 4, "dir": [0, 1, 0], "valid": true}])";
  const std::string f1 = (dir / "no_attr.exr").string();
  write_plain_exr(f1, {"R", "G", "B"}, "");
  EXPECT_THAT(read_error(f1), HasSubstr(f1));
  EXPECT_THAT(read_error(f1), HasSubstr("lightstage:lights"));
  const std::string f2 = (dir / "count.exr").string();
  write_plain_exr(f2, {"led004.R", "led004.G", "led004.B", "led005.R"}, one_light);
  EXPECT_THAT(read_error(f2), HasSubstr(f2));
  EXPECT_THAT(read_error(f2), HasSubstr("expected 3 channels"));
  const std::string f3 = (dir / "unknown.exr").string();
  write_plain_exr(f3, {"led004.R", "led004.G", "led009.B"}, one_light);
  EXPECT_THAT(read_error(f3), HasSubstr(f3));
  EXPECT_THAT(read_error(f3), HasSubstr("unknown channel 'led009.B'"));
  const std::string f4 = (dir / "badjson.exr").string();
  write_plain_exr(f4, {"led004.R", "led004.G", "led004.B"}, R"([{"id": 4}])");
  EXPECT_THAT(read_error(f4), HasSubstr(f4));
  const std::string f5 = (dir / "badsat.exr").string();
  write_plain_exr(f5, {"led004.R", "led004.G", "led004.B"},
                  R"([{"id": 4, "dir": [0, 1, 0], "valid": true, "saturates_at": [1, 0, 1]}])");
  EXPECT_THAT(read_error(f5), HasSubstr(f5));
  EXPECT_THAT(read_error(f5), HasSubstr("saturates_at must be finite and positive"));
  // A light with no direction cannot be given a cell (relighting) or a shading term (fits).
  const std::string f6 = (dir / "zerodir.exr").string();
  write_plain_exr(f6, {"led004.R", "led004.G", "led004.B"},
                  R"([{"id": 4, "dir": [0, 0, 0], "valid": true}])");
  EXPECT_THAT(read_error(f6), HasSubstr(f6));
  EXPECT_THAT(read_error(f6), HasSubstr("non-zero direction"));
  // An id beyond an int is refused by name, not wrapped onto another LED's channels.
  const std::string f7 = (dir / "hugeid.exr").string();
  write_plain_exr(f7, {"led001.R", "led001.G", "led001.B"},
                  R"([{"id": 4294967297, "dir": [0, 1, 0], "valid": true}])");
  EXPECT_THAT(read_error(f7), HasSubstr(f7));
  EXPECT_THAT(read_error(f7),
              HasSubstr("id must be an integer in [0, 2147483647], got 4294967297"));
  EXPECT_THAT(read_error(dir / "absent.exr"), HasSubstr("absent.exr"));
  // A valid minimal file reads.
  const std::string ok = (dir / "ok.exr").string();
  write_plain_exr(ok, {"led004.R", "led004.G", "led004.B"}, one_light);
  EXPECT_EQ(read_field(ok).at(1, 1, 0, 2), 1.0f);
}

// Uncompressed fields are read straight from the file, row chunks where the format puts them
// (each: its row, its byte count, its values): a chunk out of place or a value that is not finite
// is refused naming the file, never read as another row's values.
TEST(Field, RawRowsOutOfPlaceOrNotFiniteAreRefusedByName) {
  ls::testing::TempDir dir;
  const ReflectanceField field = random_field(16, 9, 3, 3);
  const std::filesystem::path path = dir / "field.exr";
  write_field(path, field);
  const std::uintmax_t chunk = 8 + 16 * 9 * sizeof(float);  // 16 pixels x 9 channels.
  const auto patch = [&](const std::filesystem::path& to, std::uintmax_t from_end,
                         const void* bytes, std::size_t count) {
    std::filesystem::copy_file(path, to);
    ls::testing::patch_from_end(to, from_end, bytes, count);
  };
  const auto planar_error = [](const std::filesystem::path& p) {
    try {
      FieldStream stream(p);
      stream.read_rows_planar(0, stream.height(), [](const PlanarRows&) {});
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("read");
  };
  // Row 4 of 9 claims to be row 5.
  const std::int32_t wrong_row = 5;
  patch(dir / "moved.exr", 5 * chunk, &wrong_row, 4);
  EXPECT_THAT(planar_error(dir / "moved.exr"), HasSubstr((dir / "moved.exr").string()));
  EXPECT_THAT(planar_error(dir / "moved.exr"), HasSubstr("row 4"));
  EXPECT_THAT(read_error(dir / "moved.exr"), HasSubstr("row 4"));
  // A NaN in row 6.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  patch(dir / "nan.exr", 3 * chunk - 8 - 20, &nan, 4);
  EXPECT_THAT(planar_error(dir / "nan.exr"), HasSubstr("non-finite"));
  EXPECT_THAT(read_error(dir / "nan.exr"), HasSubstr("non-finite"));
  // Untouched, the same file reads as written.
  expect_same(field, read_field(path));
}

TEST(Field, MemoryRefusal) {
  EXPECT_GT(available_memory_bytes(), 0u);
  try {
    require_memory(std::size_t(1) << 60, "reflectance field 4096x4096 with 150000 LEDs",
                   "use a smaller crop or fewer LEDs");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_THAT(m, HasSubstr("reflectance field 4096x4096 with 150000 LEDs needs 1073741824.0 GiB "
                             "but only "));
    EXPECT_THAT(m, HasSubstr("GiB of memory are available"));
    EXPECT_THAT(m, HasSubstr("smaller crop or fewer LEDs"));
  }
  EXPECT_NO_THROW(require_memory(1024, "a small buffer", ""));
  // Constructing a field far beyond memory throws before allocating (no crash, no OOM kill).
  try {
    ReflectanceField huge(65536, 65536, make_lights(200));
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(),
                HasSubstr("reflectance field 65536x65536 with 200 LEDs needs 9600.0 GiB"));
  }
}

// The demo field's size: 256x256 pixels, 150 LEDs = 450 channels (more than a byte counts). The
// file holds one float channel per LED and colour, named by LED id, and reads back bit-exact.
// (Write and read throughput are not a test's business: that is a benchmark's.)
TEST(Field, HundredsOfChannelsRoundTripBitExactAndNamedPerLed) {
  ls::testing::TempDir dir;
  const ReflectanceField field = random_field(256, 256, 150, 9);
  write_field(dir / "big.exr", field);
  expect_same(field, read_field(dir / "big.exr"));
  auto in = OIIO::ImageInput::open((dir / "big.exr").string());
  ASSERT_TRUE(in);
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.width, 256);
  EXPECT_EQ(spec.height, 256);
  ASSERT_EQ(spec.nchannels, 450);
  EXPECT_EQ(spec.format, OIIO::TypeDesc::FLOAT);  // Not half: bit-exact needs 32-bit floats.
  // EXR keeps channels sorted by name, so compare the sets.
  std::vector<std::string> expected;
  const char rgb[] = "RGB";
  for (int i = 0; i < 450; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "led%03d.%c", field.lights()[i / 3].led_id, rgb[i % 3]);
    expected.push_back(name);
  }
  std::vector<std::string> names = spec.channelnames;
  std::sort(expected.begin(), expected.end());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, expected);
}

}  // namespace
}  // namespace ls::capture
