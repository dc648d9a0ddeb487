#pragma once
// Sets of the one-light-at-a-time importers' tests: DiLiGenT- and .lp-layout sets written from
// the simulator's Lambertian sphere, and measures of the normals and albedo estimated from them
// against its ground truth.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/image.h"
#include "lightstage/stage.h"
#include "relight/fit/normals.h"
#include "sim/sim_stage.h"
#include "tests/support/test_support.h"

namespace ls::capture::olat_testing {

namespace fs = std::filesystem;
inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kRadToDeg = 180.0 / kPi;

// --- Writing sets
// ---------------------------------------------------------------------------------

inline void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

// Integer codes (0..2^bits-1) as an 8- or 16-bit PNG or TIFF, chosen by the extension.
inline void write_codes(const fs::path& path, int width, int height, int channels,
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

inline double srgb_encode(double linear) {
  linear = std::clamp(linear, 0.0, 1.0);
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1 / 2.4) - 0.055;
}

// Unit directions spread evenly over the cap within max_polar_deg of +Z (the camera).
inline std::vector<Eigen::Vector3d> cap_directions(int count, double max_polar_deg) {
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

inline const Eigen::Vector3d kAlbedo{0.7, 0.5, 0.3};

// A Lambertian sphere seen by a size x size orthographic camera, lit from a cap of directions.
struct SimSet {
  int size = 0;
  std::vector<Eigen::Vector3d> dirs;
  std::vector<Image> images;  // The ideal R(x, l): value per unit irradiance.
  std::vector<sim::SurfaceHit> hits;
};

inline SimSet render_sphere(int size, int lights) {
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
inline std::string direction_text(const Eigen::Vector3d& d) {
  char text[96];
  std::snprintf(text, sizeof(text), "%.9f %.9f %.9f", d.x(), d.y(), d.z());
  return text;
}

// Codes of one light's image: value * scale plus Gaussian read noise (sigma in linear full-scale
// units, seeded), through `encode`, quantised to `bits`.
inline std::vector<uint16_t> encode_image(const Image& image, const Eigen::Vector3d& scale_rgb,
                                          int bits, const std::function<double(double)>& encode,
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
inline constexpr double kReadNoise = 1e-3;

inline double max_value(const SimSet& set) {
  double m = 0;
  for (const Image& image : set.images) {
    for (float v : image.pixels) m = std::max(m, double(v));
  }
  return m;
}

// DiLiGenT layout: 001.png..., filenames.txt, light_directions.txt, light_intensities.txt (r g b
// per light; the images are R * intensity), mask.png (255 = object), 16-bit linear PNGs.
inline std::vector<Eigen::Vector3d> write_diligent(const SimSet& set, const fs::path& dir,
                                                   uint64_t seed) {
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
inline fs::path write_lp(const SimSet& set, const fs::path& dir, const std::string& extension,
                         int bits, const std::function<double(double)>& encode) {
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
inline NormalError normal_error(const relight::NormalMap& map, const SimSet& set,
                                int downsample = 1) {
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

inline relight::NormalMap robust_normals(const ReflectanceField& field) {
  relight::NormalOptions options;
  options.method = relight::NormalMethod::kRobust;
  return relight::estimate_normals(field, options);
}

// Median over unflagged pixels of albedo_c / albedo_G.
inline Eigen::Vector3d median_albedo_ratio(const relight::NormalMap& map) {
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

inline void expect_finite_nonnegative(const ReflectanceField& field) {
  for (size_t i = 0; i < field.values().size(); ++i) {
    ASSERT_TRUE(std::isfinite(field.values()[i]) && field.values()[i] >= 0)
        << "value " << i << " = " << field.values()[i];
  }
}

// The real RTI set of the shared data (absent in some checkouts: its tests skip).
inline fs::path real_lp() {
  return ls::testing::shared_data_dir() / "rti/loewenkopf_klein/dirs.lp";
}

}  // namespace ls::capture::olat_testing
