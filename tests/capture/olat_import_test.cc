// Importers of existing one-light-at-a-time sets: a real RTI set, DiLiGenT- and .lp-layout sets
// written from the simulator (normals and albedo against its ground truth), error messages, CLI.
#include "capture/olat_import.h"

#include <OpenImageIO/imageio.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <iostream>
#include <mutex>
#include <random>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "lightstage/stage.h"
#include "physics/envmap.h"
#include "relight/fit/normals.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/sim_stage.h"
#include "tests/support/test_support.h"

namespace ls::capture {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180.0 / kPi;

// --- Writing sets
// ---------------------------------------------------------------------------------

void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

// Integer codes (0..2^bits-1) as an 8- or 16-bit PNG or TIFF, chosen by the extension.
void write_codes(const fs::path& path, int width, int height, int channels,
                 const std::vector<uint16_t>& codes, int bits) {
  fs::create_directories(path.parent_path());
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out) << path;
  const OIIO::TypeDesc type = bits == 8 ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::UINT16;
  OIIO::ImageSpec spec(width, height, channels, type);
  ASSERT_TRUE(out->open(path.string(), spec)) << out->geterror();
  if (bits == 8) {
    std::vector<uint8_t> bytes(codes.begin(), codes.end());
    ASSERT_TRUE(out->write_image(type, bytes.data())) << out->geterror();
  } else {
    ASSERT_TRUE(out->write_image(type, codes.data())) << out->geterror();
  }
  out->close();
}

double srgb_encode(double linear) {
  linear = std::clamp(linear, 0.0, 1.0);
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1 / 2.4) - 0.055;
}

// Unit directions spread evenly over the cap within max_polar_deg of +Z (the camera).
std::vector<Eigen::Vector3d> cap_directions(int count, double max_polar_deg) {
  std::vector<Eigen::Vector3d> dirs;
  const double min_z = std::cos(max_polar_deg / kRadToDeg);
  const double golden_angle = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - (1.0 - min_z) * (i + 0.5) / count;
    const double r = std::sqrt(1.0 - z * z);
    dirs.emplace_back(r * std::cos(i * golden_angle), r * std::sin(i * golden_angle), z);
  }
  return dirs;
}

const Eigen::Vector3d kAlbedo{0.7, 0.5, 0.3};

// A Lambertian sphere seen by a size x size orthographic camera, lit from a cap of directions.
struct SimSet {
  int size = 0;
  std::vector<Eigen::Vector3d> dirs;
  std::vector<Image> images;  // The ideal R(x, l): value per unit irradiance.
  std::vector<sim::SurfaceHit> hits;
};

SimSet render_sphere(int size, int lights) {
  SimSet set;
  set.size = size;
  set.dirs = cap_directions(lights, 70.0);
  Stage stage = stage_with_directions(set.dirs);
  stage.camera.width = stage.camera.height = size;
  stage.camera.fov_y_deg = 0.0;
  stage.camera.ortho_height_m = 2.0;
  sim::Scene scene;
  sim::SceneMaterial material;
  material.name = "matte";
  material.base.albedo = kAlbedo;
  scene.materials.push_back(material);
  scene.spheres.push_back({Eigen::Vector3d(0, 0, 0), 0.85, 0});
  sim::SimStage sim_stage(stage, scene, 1);
  for (int l = 0; l < lights; ++l) set.images.push_back(sim_stage.one_light_image(l));
  set.hits = sim_stage.hits();
  return set;
}

// Light directions in the .lp / DiLiGenT frame (x right, y up, z toward the camera): the stage's.
std::string direction_text(const Eigen::Vector3d& d) {
  char text[96];
  std::snprintf(text, sizeof(text), "%.9f %.9f %.9f", d.x(), d.y(), d.z());
  return text;
}

// Codes of one light's image: value * scale plus Gaussian read noise (sigma in linear full-scale
// units, seeded), through `encode`, quantised to `bits`.
std::vector<uint16_t> encode_image(const Image& image, const Eigen::Vector3d& scale_rgb, int bits,
                                   const std::function<double(double)>& encode,
                                   double noise_sigma = 0.0, uint64_t seed = 0) {
  const int max_code = (1 << bits) - 1;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, noise_sigma > 0 ? noise_sigma : 1.0);
  std::vector<uint16_t> codes(image.pixels.size());
  for (size_t i = 0; i < codes.size(); ++i) {
    const double noise = noise_sigma > 0 ? gauss(rng) : 0.0;
    const double v = std::clamp(encode(image.pixels[i] * scale_rgb[i % 3] + noise), 0.0, 1.0);
    codes[i] = uint16_t(std::lround(v * max_code));
  }
  return codes;
}

// Read noise of the simulated sets: 0.1% of full scale, like the NoiseModel's default floor.
constexpr double kReadNoise = 1e-3;

double max_value(const SimSet& set) {
  double m = 0;
  for (const Image& image : set.images) {
    for (float v : image.pixels) m = std::max(m, double(v));
  }
  return m;
}

// DiLiGenT layout: 001.png..., filenames.txt, light_directions.txt, light_intensities.txt (r g b
// per light; the images are R * intensity), mask.png (255 = object), 16-bit linear PNGs.
std::vector<Eigen::Vector3d> write_diligent(const SimSet& set, const fs::path& dir, uint64_t seed) {
  std::mt19937_64 rng(seed);
  // Per-channel ranges with different means, so not dividing them out would change colours.
  std::uniform_real_distribution<double> red(0.5, 1.0), green(0.8, 1.6), blue(1.0, 2.0);
  std::vector<Eigen::Vector3d> intensities;
  for (size_t l = 0; l < set.images.size(); ++l) {
    intensities.emplace_back(red(rng), green(rng), blue(rng));
  }
  const double exposure = 0.9 / (max_value(set) * 2.0);  // Brightest code ~ 0.9 full scale.
  std::string names, dirs, ints;
  for (size_t l = 0; l < set.images.size(); ++l) {
    char name[32];
    std::snprintf(name, sizeof(name), "%03zu.png", l + 1);
    names += std::string(name) + "\n";
    dirs += direction_text(set.dirs[l]) + "\n";
    char text[96];
    std::snprintf(text, sizeof(text), "%.6f %.6f %.6f\n", intensities[l].x(), intensities[l].y(),
                  intensities[l].z());
    ints += text;
    write_codes(dir / name, set.size, set.size, 3,
                encode_image(
                    set.images[l], exposure * intensities[l], 16, [](double v) { return v; },
                    kReadNoise, seed + l),
                16);
  }
  write_text(dir / "filenames.txt", names);
  write_text(dir / "light_directions.txt", dirs);
  write_text(dir / "light_intensities.txt", ints);
  std::vector<uint16_t> mask(size_t(set.size) * set.size, 0);
  for (const sim::SurfaceHit& h : set.hits) {
    if (h.hit) mask[size_t(h.pixel_y) * set.size + h.pixel_x] = 255;
  }
  write_codes(dir / "mask.png", set.size, set.size, 1, mask, 8);
  return intensities;
}

// An .lp set: count, then "images/light_NNN.EXT x y z" per light; codes through `encode`.
fs::path write_lp(const SimSet& set, const fs::path& dir, const std::string& extension, int bits,
                  const std::function<double(double)>& encode) {
  const double exposure = 0.95 / max_value(set);
  std::string lp = std::to_string(set.images.size()) + "\n";
  for (size_t l = 0; l < set.images.size(); ++l) {
    char name[64];
    std::snprintf(name, sizeof(name), "images/light_%03zu%s", l, extension.c_str());
    lp += std::string(name) + " " + direction_text(set.dirs[l]) + "\n";
    write_codes(dir / name, set.size, set.size, 3,
                encode_image(set.images[l], Eigen::Vector3d::Constant(exposure), bits, encode,
                             kReadNoise, 1000 + l),
                bits);
  }
  write_text(dir / "lights.lp", lp);
  return dir / "lights.lp";
}

// --- Measuring
// ------------------------------------------------------------------------------------

struct NormalError {
  double mean_deg = 0;
  int pixels = 0;
  int flagged = 0;  // Of the object's pixels.
};

// Mean angle between the estimated and the simulator's normals over the object's unflagged pixels.
NormalError normal_error(const relight::NormalMap& map, const SimSet& set, int downsample = 1) {
  NormalError e;
  for (const sim::SurfaceHit& h : set.hits) {
    if (!h.hit) continue;
    if (downsample > 1 && (h.pixel_x % downsample != 0 || h.pixel_y % downsample != 0)) continue;
    const int x = h.pixel_x / downsample, y = h.pixel_y / downsample;
    if (map.flags.at(x, y, 0) != 0) {
      ++e.flagged;
      continue;
    }
    const Eigen::Vector3d n(map.normal.at(x, y, 0), map.normal.at(x, y, 1), map.normal.at(x, y, 2));
    // Downsampled: compare with the mean normal of the block it averages.
    Eigen::Vector3d truth = h.normal;
    if (downsample > 1) {
      truth.setZero();
      for (int dy = 0; dy < downsample; ++dy) {
        for (int dx = 0; dx < downsample; ++dx) {
          const sim::SurfaceHit& b = set.hits[size_t(h.pixel_y + dy) * set.size + h.pixel_x + dx];
          if (b.hit) truth += b.normal;
        }
      }
      truth.normalize();
    }
    e.mean_deg += std::acos(std::clamp(n.normalized().dot(truth), -1.0, 1.0)) * kRadToDeg;
    ++e.pixels;
  }
  if (e.pixels > 0) e.mean_deg /= e.pixels;
  return e;
}

relight::NormalMap robust_normals(const ReflectanceField& field) {
  relight::NormalOptions options;
  options.method = relight::NormalMethod::kRobust;
  return relight::estimate_normals(field, options);
}

// Median over unflagged pixels of albedo_c / albedo_G.
Eigen::Vector3d median_albedo_ratio(const relight::NormalMap& map) {
  std::vector<double> ratios[3];
  for (int y = 0; y < map.flags.height; ++y) {
    for (int x = 0; x < map.flags.width; ++x) {
      if (map.flags.at(x, y, 0) != 0 || map.albedo.at(x, y, 1) <= 0) continue;
      for (int c = 0; c < 3; ++c)
        ratios[c].push_back(map.albedo.at(x, y, c) / map.albedo.at(x, y, 1));
    }
  }
  Eigen::Vector3d median;
  for (int c = 0; c < 3; ++c) {
    if (ratios[c].empty()) return Eigen::Vector3d::Zero();
    std::nth_element(ratios[c].begin(), ratios[c].begin() + ratios[c].size() / 2, ratios[c].end());
    median[c] = ratios[c][ratios[c].size() / 2];
  }
  return median;
}

void expect_finite_nonnegative(const ReflectanceField& field) {
  for (size_t i = 0; i < field.values().size(); ++i) {
    ASSERT_TRUE(std::isfinite(field.values()[i]) && field.values()[i] >= 0)
        << "value " << i << " = " << field.values()[i];
  }
}

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

fs::path real_lp() { return ls::testing::shared_data_dir() / "rti/loewenkopf_klein/dirs.lp"; }

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
  EXPECT_FALSE(undivided_summary.notes.empty());
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
  killed.on_progress = [](int done, int total) {
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

// --- CLI
// ------------------------------------------------------------------------------------------

TEST(OlatImport, CliImportsRealSetAndRejectsBadLpWithExitTwo) {
  if (!fs::exists(real_lp())) GTEST_SKIP() << real_lp() << " is absent";
  ls::testing::TempDir tmp;
  std::string output;
  const std::string cli = ls::testing::cli_path().string();
  int rc = ls::testing::run_command(cli + " import '" + real_lp().string() + "' --quiet --out '" +
                                        (tmp / "lion.exr").string() + "'",
                                    &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_NE(output.find("RTI .lp file"), std::string::npos) << output;
  EXPECT_NE(output.find("240 images"), std::string::npos) << output;
  EXPECT_NE(output.find("sRGB curve"), std::string::npos) << output;
  const ReflectanceField field = read_field(tmp / "lion.exr");
  EXPECT_EQ(field.num_lights(), 240);
  EXPECT_EQ(field.width(), 64);
  EXPECT_EQ(field.height(), 43);
  EXPECT_TRUE(fs::exists(tmp / "lion.preview.png"));

  write_text(tmp / "bad.lp", "2\nnothing.jpg 0 0 1\n");
  // stdout to /dev/null: what comes back is stderr only.
  rc = ls::testing::run_command("{ " + cli + " import '" + (tmp / "bad.lp").string() + "' --out '" +
                                    (tmp / "bad.exr").string() + "' 2>&1 >/dev/null; }",
                                &output);
  EXPECT_EQ(rc, 2) << output;
  EXPECT_NE(output.find("bad.lp:1: count"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(tmp / "bad.exr"));
}

TEST(OlatImport, CliImportsATimeLapseWithItsTimesInOneCommand) {
  ls::testing::TempDir tmp;
  const SimSet set = render_sphere(12, 20);
  for (const char* step : {"a_morning", "b_noon", "c_evening"}) {
    write_lp(set, tmp / "series" / step, ".png", 16, [](double v) { return v; });
  }
  const std::string cli = ls::testing::cli_path().string();
  std::string output;
  // One set with its time.
  int rc = ls::testing::run_command(cli + " import '" + (tmp / "series" / "b_noon").string() +
                                        "' --time 3600 --quiet --out '" +
                                        (tmp / "one.exr").string() + "'",
                                    &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_EQ(read_field(tmp / "one.exr").scene_time_s, 3600.0);
  // The folder of steps, a time each: field_t000.exr ... in the steps' name order.
  rc = ls::testing::run_command(cli + " import '" + (tmp / "series").string() +
                                    "' --time 0 3600 7200.5 --quiet --out '" +
                                    (tmp / "fields").string() + "'",
                                &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_NE(output.find("wrote 3 time steps"), std::string::npos) << output;
  const double expected[3] = {0, 3600, 7200.5};
  for (int i = 0; i < 3; ++i) {
    const fs::path field = tmp / "fields" / ("field_t00" + std::to_string(i) + ".exr");
    EXPECT_EQ(read_field(field).scene_time_s, expected[i]) << field;
  }
  // Or an interval; a count of times that does not match is refused before anything is written.
  rc = ls::testing::run_command(cli + " import '" + (tmp / "series").string() +
                                    "' --interval 60 --quiet --out '" + (tmp / "spaced").string() +
                                    "'",
                                &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_EQ(read_field(tmp / "spaced" / "field_t002.exr").scene_time_s, 120.0);
  rc = ls::testing::run_command("{ " + cli + " import '" + (tmp / "series").string() +
                                    "' --time 0 60 --out '" + (tmp / "short").string() +
                                    "' 2>&1 >/dev/null; }",
                                &output);
  EXPECT_EQ(rc, 2) << output;
  EXPECT_NE(output.find("--time: expected one time per set (3 sets), got 2"), std::string::npos)
      << output;
  EXPECT_FALSE(fs::exists(tmp / "short"));
}

}  // namespace
}  // namespace ls::capture
