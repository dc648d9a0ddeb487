#include "physics/envmap.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "tests/support/test_support.h"

namespace {

namespace fs = std::filesystem;
using ls::Image;
using ls::physics::EnvironmentMap;

void expect_dir_near(const Eigen::Vector3d& actual, const Eigen::Vector3d& expected,
                     double tol = 1e-12) {
  EXPECT_LT((actual - expected).norm(), tol)
      << "got (" << actual.transpose() << "), expected (" << expected.transpose() << ")";
}

TEST(EnvmapTest, ConventionAnchors) {
  for (double u : {0.0, 0.3, 0.9}) expect_dir_near(EnvironmentMap::direction(u, 0.0), {0, 1, 0});
  expect_dir_near(EnvironmentMap::direction(0.5, 1.0), {0, -1, 0});
  expect_dir_near(EnvironmentMap::direction(0.5, 0.5), {0, 0, -1});  // Map centre: -Z.
  expect_dir_near(EnvironmentMap::direction(0.75, 0.5), {1, 0, 0});  // u = 0.75: +X.
  expect_dir_near(EnvironmentMap::direction(0.25, 0.5), {-1, 0, 0});
  expect_dir_near(EnvironmentMap::direction(0.0, 0.5), {0, 0, 1});  // Seam: +Z (the camera).
  EXPECT_LT((EnvironmentMap::uv({1, 0, 0}) - Eigen::Vector2d(0.75, 0.5)).norm(), 1e-12);
  EXPECT_LT((EnvironmentMap::uv({0, 0, -1}) - Eigen::Vector2d(0.5, 0.5)).norm(), 1e-12);

  const EnvironmentMap map(Image(64, 32, 3, 1.0f));
  // Top row looks (nearly) up, the centre pixel (nearly) along -Z.
  EXPECT_GT(map.pixel_direction(10, 0).y(), std::cos(std::numbers::pi / 32));
  EXPECT_LT(map.pixel_direction(20, 31).y(), -std::cos(std::numbers::pi / 32));
  EXPECT_LT((map.pixel_direction(32, 16) - Eigen::Vector3d(0, 0, -1)).norm(), 0.1);
  EXPECT_LT((map.pixel_direction(48, 16) - Eigen::Vector3d(1, 0, 0)).norm(), 0.1);
}

TEST(EnvmapTest, DirectionUvRoundTrip) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    const double u = unit(rng), v = 1e-4 + (1 - 2e-4) * unit(rng);
    const Eigen::Vector3d d = EnvironmentMap::direction(u, v);
    EXPECT_NEAR(d.norm(), 1.0, 1e-12);
    const Eigen::Vector2d back = EnvironmentMap::uv(d);
    EXPECT_NEAR(back.x(), u, 1e-9) << "v=" << v;
    EXPECT_NEAR(back.y(), v, 1e-9);
    // And direction -> uv -> direction for arbitrary (non-unit) vectors.
    const Eigen::Vector3d w(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5);
    const Eigen::Vector2d uv_w = EnvironmentMap::uv(w);
    EXPECT_GE(uv_w.x(), 0.0);
    EXPECT_LT(uv_w.x(), 1.0);
    expect_dir_near(EnvironmentMap::direction(uv_w.x(), uv_w.y()), w.normalized(), 1e-9);
  }
}

TEST(EnvmapTest, PixelSolidAnglesSumTo4PiAndIntegralWeightsThem) {
  for (int h : {1, 2, 7, 64, 512}) {
    const EnvironmentMap map(Image(2 * h, h, 3, 1.0f));
    double sum_sr = 0;
    for (int y = 0; y < h; ++y) {
      const double row_sr = map.pixel_solid_angle_sr(y);
      EXPECT_GT(row_sr, 0.0);
      sum_sr += row_sr * map.width();
    }
    EXPECT_NEAR(sum_sr, 4 * std::numbers::pi, 1e-12) << h;
    // Rows are symmetric about the equator.
    EXPECT_NEAR(map.pixel_solid_angle_sr(0), map.pixel_solid_angle_sr(h - 1), 1e-15);
  }
  // integral() of L = (1, 2, 3) is 4 pi (1, 2, 3); of L = max(0, d.y) (only R) it is pi.
  Image image(256, 128, 3, 0.0f);
  const EnvironmentMap probe(Image(256, 128, 3));
  for (int y = 0; y < 128; ++y) {
    for (int x = 0; x < 256; ++x) {
      image.at(x, y, 0) = float(std::max(0.0, probe.pixel_direction(x, y).y()));
      image.at(x, y, 1) = 2.0f;
      image.at(x, y, 2) = 3.0f;
    }
  }
  const Eigen::Vector3d integral = EnvironmentMap(image).integral();
  EXPECT_NEAR(integral[0], std::numbers::pi, 1e-3);
  EXPECT_NEAR(integral[1], 8 * std::numbers::pi, 1e-5);
  EXPECT_NEAR(integral[2], 12 * std::numbers::pi, 1e-5);
}

// A map whose only light is a bright patch around direction `dir`.
EnvironmentMap spot_map(const Eigen::Vector3d& dir) {
  const EnvironmentMap probe(Image(128, 64, 3));
  Image image(128, 64, 3, 0.0f);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 128; ++x) {
      if (probe.pixel_direction(x, y).dot(dir) > std::cos(0.2)) {
        for (int c = 0; c < 3; ++c) image.at(x, y, c) = 10.0f;
      }
    }
  }
  return EnvironmentMap(image);
}

// Rotating by +alpha turns the content by +alpha about +Y (right-hand rule): +90 degrees takes
// what was at -Z to -X and what was at +X to -Z.
TEST(EnvmapTest, RotationSignIsRightHandedAboutY) {
  const EnvironmentMap behind = spot_map({0, 0, -1});
  EXPECT_FLOAT_EQ(behind.radiance_toward({0, 0, -1})[0], 10.0f);
  EXPECT_FLOAT_EQ(behind.radiance_toward({-1, 0, 0})[0], 0.0f);
  EXPECT_FLOAT_EQ(behind.radiance_toward({-1, 0, 0}, 90.0)[0], 10.0f);
  EXPECT_FLOAT_EQ(behind.radiance_toward({0, 0, -1}, 90.0)[0], 0.0f);
  EXPECT_FLOAT_EQ(behind.radiance_toward({1, 0, 0}, 90.0)[0], 0.0f);
  EXPECT_FLOAT_EQ(behind.radiance_toward({1, 0, 0}, -90.0)[0], 10.0f);

  const EnvironmentMap right = spot_map({1, 0, 0});
  EXPECT_FLOAT_EQ(right.radiance_toward({0, 0, -1}, 90.0)[1], 10.0f);
  EXPECT_FLOAT_EQ(right.radiance_toward({0, 0, 1}, 90.0)[1], 0.0f);
  // A full turn changes nothing; rotating content at the zenith does nothing either.
  const EnvironmentMap top = spot_map({0, 1, 0});
  for (double deg : {0.0, 37.0, 90.0, 360.0}) {
    EXPECT_FLOAT_EQ(top.radiance_toward({0, 1, 0}, deg)[2], 10.0f) << deg;
  }
  EXPECT_FLOAT_EQ(behind.radiance_toward({0, 0, -1}, 360.0)[0], 10.0f);
}

// Box filtering keeps the map's light: a constant map filters to texels of that radiance times
// each texel's solid angle, summing to 4 pi L at any coarse width and rotation.
TEST(EnvmapTest, BoxFilterKeepsTheIntegralAtAnyWidthAndRotation) {
  const EnvironmentMap map(Image(64, 32, 3, 2.0f));
  for (const int width : {4, 16, 24, 128}) {
    for (const double rotation_deg : {0.0, 33.0}) {
      const std::vector<ls::physics::CoarseTexel> texels =
          ls::physics::box_filter_environment(map, width, rotation_deg);
      ASSERT_EQ(int(texels.size()), width * width / 2);
      Eigen::Vector3d sum(0, 0, 0);
      for (const ls::physics::CoarseTexel& t : texels) sum += t.radiance_x_sr;
      EXPECT_NEAR(sum[1], 8 * std::numbers::pi, 1e-9) << width << " " << rotation_deg;
      const ls::physics::CoarseTexel& t = texels[size_t(width) + 1];
      const Eigen::Vector3d unrotated =
          EnvironmentMap::direction((t.x + 0.5) / width, (t.y + 0.5) / (width / 2));
      EXPECT_LT((t.dir_in_stage - ls::physics::rotate_about_y(unrotated, rotation_deg)).norm(),
                1e-12);
    }
  }
  EXPECT_THROW(ls::physics::box_filter_environment(map, 6 + 1), ls::InputError);
  EXPECT_THROW(ls::physics::box_filter_environment(map, 2), ls::InputError);
}

TEST(EnvmapTest, BilinearLookupReproducesPixelCentresAndWraps) {
  Image image(16, 8, 3, 0.0f);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 16; ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = float(x + 16 * y + c);
    }
  }
  const EnvironmentMap map(image);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 16; ++x) {
      const Eigen::Vector3f l = map.radiance_toward(map.pixel_direction(x, y));
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(l[c], image.at(x, y, c), 1e-4) << x << "," << y;
    }
  }
  // At u = 0 (the seam) the lookup is halfway between the last and the first column.
  const Eigen::Vector3f seam = map.radiance_toward(EnvironmentMap::direction(0.0, 4.5 / 8));
  EXPECT_NEAR(seam[0], 0.5 * (image.at(15, 4, 0) + image.at(0, 4, 0)), 1e-4);
}

TEST(EnvmapTest, OneChannelMapIsGreyAndFourChannelsDropAlpha) {
  Image grey(8, 4, 1, 2.5f);
  const EnvironmentMap g(grey);
  ASSERT_EQ(g.radiance().channels, 3);
  EXPECT_EQ(g.radiance().at(3, 2, 2), 2.5f);
  Image rgba(8, 4, 4, 1.0f);
  for (size_t i = 0; i < rgba.num_pixels(); ++i) rgba.pixels[i * 4 + 3] = -7.0f;  // Alpha ignored.
  const EnvironmentMap m(rgba);
  EXPECT_EQ(m.radiance().channels, 3);
  EXPECT_EQ(m.radiance().at(1, 1, 2), 1.0f);
}

struct Reference {
  const char* file;
  double mean[3];
  double max_value;
  int max_x, max_y;
};

// Reference numbers from /work/shared/data/README.md (independent decoder).
const Reference kReferences[] = {
    {"blouberg_sunrise_2_1k.hdr", {0.53542, 0.52399, 0.53373}, 50.5, 57, 232},
    {"pedestrian_overpass_1k.hdr", {0.5048, 0.58123, 0.68113}, 33.5, 657, 248},
    {"royal_esplanade_1k.hdr", {2.7768, 2.2266, 1.3018}, 49664, 92, 18},
    {"spruit_sunrise_1k.hdr", {0.32357, 0.36829, 0.36903}, 828, 613, 233},
};

TEST(EnvmapTest, LoadsEverySharedMapAndMatchesReferenceStatistics) {
  const fs::path dir = ls::testing::shared_data_dir() / "envmaps";
  if (!fs::is_directory(dir)) GTEST_SKIP() << dir << " is absent";
  int loaded = 0, exr = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string ext = entry.path().extension().string();
    if (ext != ".hdr" && ext != ".exr") continue;
    SCOPED_TRACE(entry.path().string());
    const EnvironmentMap map = EnvironmentMap::load(entry.path());
    ++loaded;
    exr += ext == ".exr";
    EXPECT_EQ(map.width(), 2 * map.height());
    EXPECT_EQ(map.source(), entry.path().string());
    const Eigen::Vector3d integral = map.integral();
    EXPECT_GT(integral.sum(), 0.0);  // Every real map has some light; DWAB decoded to non-zero.
    EXPECT_TRUE(integral.allFinite());

    const std::string name = entry.path().filename().string();
    for (const Reference& ref : kReferences) {
      if (name != ref.file) continue;
      const Image& image = map.radiance();
      double sum[3] = {0, 0, 0};
      double max_value = -1;
      int max_x = -1, max_y = -1;
      for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
          for (int c = 0; c < 3; ++c) {
            const double v = image.at(x, y, c);
            sum[c] += v;
            if (v > max_value) max_value = v, max_x = x, max_y = y;
          }
        }
      }
      for (int c = 0; c < 3; ++c) {
        const double mean = sum[c] / double(image.num_pixels());
        EXPECT_NEAR(mean, ref.mean[c], 1e-3 * ref.mean[c]) << "channel " << c;
      }
      EXPECT_NEAR(max_value, ref.max_value, 1e-6 * ref.max_value)
          << "first maximum at (" << max_x << ", " << max_y << ")";
      // The maximum may be tied (blouberg: x=56 and x=57 on row 232); the reference's pixel must
      // hold it, which also pins the row order (row 0 = zenith) and the column origin.
      const double at_reference =
          std::max({image.at(ref.max_x, ref.max_y, 0), image.at(ref.max_x, ref.max_y, 1),
                    image.at(ref.max_x, ref.max_y, 2)});
      EXPECT_EQ(at_reference, max_value);
    }
  }
  EXPECT_EQ(loaded, 9);
  EXPECT_EQ(exr, 4);  // studio, sky, night, forest: DWAB-compressed half EXR.
}

// Signed integral of the raw file: what a repaired map must keep.
Eigen::Vector3d raw_integral(const Image& raw) {
  const EnvironmentMap geometry(Image(raw.width, raw.height, 3));
  Eigen::Vector3d sum(0, 0, 0);
  for (int y = 0; y < raw.height; ++y) {
    for (int x = 0; x < raw.width; ++x) {
      for (int c = 0; c < 3; ++c) sum[c] += raw.at(x, y, c) * geometry.pixel_solid_angle_sr(y);
    }
  }
  return sum;
}

// DWAB rings around the sun in sky.exr (down to -3394 next to 22672): load() must repair that
// to non-negative radiance while keeping the map's integral.
TEST(EnvmapTest, LossyCompressionRingingIsRepairedKeepingEnergy) {
  const fs::path sky = ls::testing::shared_data_dir() / "envmaps" / "sky.exr";
  if (!fs::exists(sky)) GTEST_SKIP() << sky << " is absent";
  const Image raw = ls::read_image(sky);
  const EnvironmentMap map = EnvironmentMap::load(sky);
  EXPECT_GT(map.negative_values_repaired(), 0);
  for (float v : map.radiance().pixels) ASSERT_GE(v, 0.0f);
  const Eigen::Vector3d expected = raw_integral(raw), actual = map.integral();
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(actual[c], expected[c], 1e-5 * expected[c]) << c;

  // A float file with one negative value: zeroed, its 8x8 block's energy kept.
  ls::testing::TempDir tmp;
  Image image(32, 16, 3, 1.0f);
  image.at(5, 3, 0) = -2.0f;
  const fs::path file = tmp / "negative_map.exr";
  ls::write_exr(file, image);
  const EnvironmentMap repaired = EnvironmentMap::load(file);
  EXPECT_EQ(repaired.negative_values_repaired(), 1);
  EXPECT_EQ(repaired.radiance().at(5, 3, 0), 0.0f);
  EXPECT_LT(repaired.radiance().at(4, 3, 0), 1.0f);  // Same block: scaled down.
  EXPECT_EQ(repaired.radiance().at(8, 3, 0), 1.0f);  // Next block: untouched.
  EXPECT_EQ(repaired.radiance().at(4, 3, 1), 1.0f);  // Other channels: untouched.
  EXPECT_NEAR(repaired.integral()[0], raw_integral(image)[0], 1e-6 * raw_integral(image)[0]);
  EXPECT_EQ(EnvironmentMap(Image(32, 16, 3, 1.0f)).negative_values_repaired(), 0);
}

// Expects `fn` to throw an InputError whose message contains every one of `parts`.
template <class Fn>
void expect_input_error(Fn fn, const std::vector<std::string>& parts) {
  try {
    fn();
    ADD_FAILURE() << "no InputError thrown";
  } catch (const ls::InputError& e) {
    for (const std::string& part : parts) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos)
          << "message \"" << e.what() << "\" lacks \"" << part << "\"";
    }
  }
}

TEST(EnvmapTest, RejectsNonFiniteAndNegativeRadianceNamingFileAndPixel) {
  ls::testing::TempDir tmp;
  Image image(8, 4, 3, 1.0f);
  image.at(3, 1, 1) = std::nanf("");
  const fs::path nan_file = tmp / "nan_map.exr";
  ls::write_exr(nan_file, image);
  expect_input_error([&] { EnvironmentMap::load(nan_file); },
                     {nan_file.string(), "pixel (x=3, y=1) channel G",
                      "radiance must be finite and >= 0, got nan"});

  image.at(3, 1, 1) = 1.0f;
  image.at(6, 2, 2) = -0.5f;
  expect_input_error([&] { EnvironmentMap(image, "negative.exr"); },
                     {"negative.exr: pixel (x=6, y=2) channel B", "got -0.5"});

  image.at(6, 2, 2) = INFINITY;
  expect_input_error([&] { EnvironmentMap(image, "in-memory.exr"); },
                     {"in-memory.exr: pixel (x=6, y=2) channel B", "got inf"});
}

// A map file that is not RGB radiance: an 8-bit preview (display-referred), a grey or an XYZ map.
TEST(EnvmapTest, LoadRefusesAFileThatIsNotRgbRadianceSayingWhatItIs) {
  ls::testing::TempDir tmp;
  const Image rgb(8, 4, 3, 1.0f);
  const fs::path png = tmp / "preview.png";
  ls::write_png_preview(png, rgb, 0.0);
  expect_input_error([&] { EnvironmentMap::load(png); },
                     {png.string(), "display-referred", "HDR map (.exr or .hdr)"});
  const fs::path grey = tmp / "grey.exr";
  ls::write_exr(grey, Image(8, 4, 1, 1.0f));
  expect_input_error([&] { EnvironmentMap::load(grey); },
                     {grey.string(), "channels: 1 (Y), a grey map", "expected RGB radiance"});
  Image xyz(8, 4, 3, 1.0f);
  xyz.channel_names = {"X", "Y", "Z"};
  const fs::path xyz_file = tmp / "xyz.exr";
  ls::write_exr(xyz_file, xyz);
  expect_input_error([&] { EnvironmentMap::load(xyz_file); },
                     {xyz_file.string(), "channels X, Y, Z", "expected RGB radiance"});
  const fs::path ok = tmp / "rgb.exr";
  ls::write_exr(ok, rgb);
  EXPECT_EQ(EnvironmentMap::load(ok).width(), 8);
}

TEST(EnvmapTest, RejectsWrongChannelCountAndAspect) {
  ls::testing::TempDir tmp;
  const fs::path two_channel = tmp / "two_channel.exr";
  Image two(8, 4, 2, 1.0f);
  two.channel_names = {"R", "G"};
  ls::write_exr(two_channel, two);
  expect_input_error([&] { EnvironmentMap::load(two_channel); },
                     {two_channel.string(), "channels: expected 1, 3 or 4 channels", "got 2"});

  // Five channels: used where R, G and B are named among them, refused where nothing says which.
  Image five(8, 4, 5, 0.5f);
  five.channel_names = {"A", "B", "G", "R", "Z"};
  five.at(1, 1, 3) = 2.0f;  // R.
  const fs::path named = tmp / "named_five.exr";
  ls::write_exr(named, five);
  EXPECT_EQ(EnvironmentMap::load(named).radiance().at(1, 1, 0), 2.0f);
  five.channel_names = {"c0", "c1", "c2", "c3", "c4"};
  const fs::path unnamed = tmp / "unnamed_five.exr";
  ls::write_exr(unnamed, five);
  expect_input_error([&] { EnvironmentMap::load(unnamed); },
                     {unnamed.string(), "channels named R, G and B", "got 5"});

  // A map of -1 everywhere is not compression ringing: refused, not clamped to black.
  const fs::path all_negative = tmp / "all_negative.exr";
  ls::write_exr(all_negative, Image(16, 8, 3, -1.0f));
  expect_input_error([&] { EnvironmentMap::load(all_negative); },
                     {all_negative.string(), "negative values hold", "not a radiance map"});

  const fs::path wide = tmp / "three_to_one.exr";
  ls::write_exr(wide, Image(12, 4, 3, 1.0f));
  expect_input_error(
      [&] { EnvironmentMap::load(wide); },
      {wide.string(), "size: a lat-long map must be twice as wide as it is tall", "got 12x4"});
  expect_input_error([&] { EnvironmentMap(Image(300, 200, 3, 1.0f), "tall.hdr"); },
                     {"tall.hdr: size:", "got 300x200"});
}

// The first half of a real file's bytes: read_image must notice and name the file.
TEST(EnvmapTest, TruncatedRealFilesGiveInputErrorNamingTheFile) {
  const fs::path dir = ls::testing::shared_data_dir() / "envmaps";
  if (!fs::is_directory(dir)) GTEST_SKIP() << dir << " is absent";
  ls::testing::TempDir tmp;
  for (const char* name : {"studio.exr", "blouberg_sunrise_2_1k.hdr"}) {
    const fs::path source = dir / name;
    ASSERT_TRUE(fs::exists(source)) << source;
    std::ifstream in(source, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const fs::path truncated = tmp / (std::string("truncated_") + name);
    std::ofstream(truncated, std::ios::binary).write(bytes.data(), bytes.size() / 2);
    SCOPED_TRACE(truncated.string());
    expect_input_error([&] { EnvironmentMap::load(truncated); }, {truncated.string()});
  }
  expect_input_error([&] { EnvironmentMap::load(tmp / "missing.exr"); },
                     {(tmp / "missing.exr").string()});
}

}  // namespace
