#include "relight/fit/normals.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <optional>
#include <random>

#include "lightstage/angles.h"
#include "lightstage/errors.h"
#include "lightstage/stage.h"
#include "relight/fit/fit.h"
#include "relight/fit/noise_from_data.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
#include "tests/relight/fit/fit_fixtures.h"
#include "tests/support/test_support.h"

namespace ls::relight {
namespace {

using fit_testing::render_field;
using fit_testing::SimField;

Stage dome_stage(int leds, int image_size, double view_height_m) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(leds, -11.5));
  stage.camera.width = stage.camera.height = image_size;
  stage.camera.fov_y_deg = 0.0;
  stage.camera.ortho_height_m = view_height_m;
  return stage;
}

struct Bump {
  double x, y, height, width;
};

// A height field over [-1, 1]^2 facing the camera, made of Gaussian bumps.
sim::Scene bumpy_scene(const physics::brdf::Material& material, const std::vector<Bump>& bumps) {
  sim::Scene scene;
  sim::SceneMaterial m;
  m.name = "surface";
  m.base = material;
  scene.materials.push_back(m);
  sim::HeightField hf;
  hf.resolution = 128;
  hf.heights.resize(size_t(hf.resolution) * hf.resolution);
  for (int i = 0; i < hf.resolution; ++i) {
    for (int j = 0; j < hf.resolution; ++j) {
      const double px = -1 + 2.0 * j / (hf.resolution - 1);
      const double py = 1 - 2.0 * i / (hf.resolution - 1);
      double h = 0;
      for (const Bump& b : bumps) {
        const double r2 = (px - b.x) * (px - b.x) + (py - b.y) * (py - b.y);
        h += b.height * std::exp(-0.5 * r2 / (b.width * b.width));
      }
      hf.heights[size_t(i) * hf.resolution + j] = float(h);
    }
  }
  scene.height_fields.push_back(hf);
  return scene;
}

struct AngularError {
  double mean_deg = 0;
  int pixels = 0;
  int flagged = 0;
};

AngularError normal_error(const NormalMap& map, const std::vector<sim::SurfaceHit>& hits) {
  AngularError e;
  for (const sim::SurfaceHit& h : hits) {
    if (!h.hit) continue;
    if (map.flags.at(h.pixel_x, h.pixel_y, 0) != 0) {
      ++e.flagged;
      continue;
    }
    const Eigen::Vector3d n(map.normal.at(h.pixel_x, h.pixel_y, 0),
                            map.normal.at(h.pixel_x, h.pixel_y, 1),
                            map.normal.at(h.pixel_x, h.pixel_y, 2));
    e.mean_deg += std::acos(std::clamp(n.normalized().dot(h.normal), -1.0, 1.0)) * kRadToDeg;
    ++e.pixels;
  }
  if (e.pixels > 0) e.mean_deg /= e.pixels;
  return e;
}

void expect_finite(const Image& image) {
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    ASSERT_TRUE(std::isfinite(image.pixels[i])) << "pixel value " << i << " is not finite";
  }
}

TEST(EstimateNormals, NoisyLambertianHeightFieldUnderOneDegree) {
  physics::brdf::Material matte;
  matte.albedo = {0.7, 0.5, 0.3};
  const sim::Scene scene =
      bumpy_scene(matte, {{-0.4, 0.3, 0.12, 0.25}, {0.35, -0.2, 0.1, 0.2}, {0.2, 0.5, 0.06, 0.15}});
  const NoiseModel noise;  // Defaults: 1e-3 floor, ~2% at R = 0.2.
  const SimField sim = render_field(dome_stage(150, 48, 1.8), scene, noise, 7);

  NormalOptions options;
  options.noise = noise;
  for (const NormalMethod method : {NormalMethod::kLeastSquares, NormalMethod::kRobust}) {
    options.method = method;
    const NormalMap map = estimate_normals(sim.field, options);
    const AngularError e = normal_error(map, sim.hits);
    std::cout << (method == NormalMethod::kRobust ? "robust" : "least squares")
              << ": mean angular error " << e.mean_deg << " deg over " << e.pixels << " pixels, "
              << e.flagged << " flagged\n";
    // Measured: 0.18 deg for both methods (48x48, 150 LEDs, seed 7); asserted with a ~3x margin.
    EXPECT_LT(e.mean_deg, 0.5);
    EXPECT_EQ(e.flagged, 0);
    expect_finite(map.normal);
    expect_finite(map.albedo);
    expect_finite(map.confidence);
  }
}

// Pixels whose every sample is 0 (outside an import's mask) have no signal: marked kNoSignal and
// counted apart from the flagged pixels, whose count stays that of the pixels with signal; the fit
// and its maps read back keep the same count.
TEST(EstimateNormals, PixelsWithNoSignalAreCountedApartFromTheFlagged) {
  physics::brdf::Material matte;
  matte.albedo = {0.7, 0.5, 0.3};
  const NoiseModel noise;
  SimField sim = render_field(dome_stage(150, 48, 1.8),
                              bumpy_scene(matte, {{-0.4, 0.3, 0.12, 0.25}}), noise, 7);
  for (int y = 2; y < 8; ++y) {
    for (int x = 4; x < 9; ++x) {
      std::fill_n(sim.field.pixel(x, y), 3 * sim.field.num_lights(), 0.0f);
    }
  }
  NormalOptions options;
  options.noise = noise;
  const NormalMap map = estimate_normals(sim.field, options);
  EXPECT_EQ(map.empty_pixels, 30);
  EXPECT_EQ(map.flagged_pixels, 0);
  EXPECT_EQ(int(map.flags.at(5, 3, 0)), kNoSignal);
  EXPECT_EQ(map.normal.at(5, 3, 2), 0.0f);

  FitOptions fit_options;
  fit_options.normals.noise = noise;
  const ModelMaps maps = fit_models(sim.field, fit_options);
  EXPECT_EQ(maps.summary.empty, 30);
  EXPECT_EQ(maps.summary.fitted + maps.summary.flagged + maps.summary.empty, 48 * 48);
  EXPECT_NE(maps.summary.to_string().find("30 with no signal (every sample 0"), std::string::npos)
      << maps.summary.to_string();
  testing::TempDir dir;
  write_model_maps(dir / "maps.exr", maps);
  const FitSummary back = read_model_maps(dir / "maps.exr").summary;
  EXPECT_EQ(back.empty, 30);
  EXPECT_EQ(back.flagged, maps.summary.flagged);
}

// A field with no measured noise (an import) gets its noise from its own residuals: on a matte
// scene with known noise, both terms within 15% of the truth, at two noise levels, whatever the
// default model the normals start from.
TEST(NoiseFromData, RecoversReadAndShotVarianceOfAMatteScene) {
  physics::brdf::Material matte;
  matte.albedo = {0.7, 0.5, 0.3};
  const sim::Scene scene =
      bumpy_scene(matte, {{-0.4, 0.3, 0.12, 0.25}, {0.35, -0.2, 0.1, 0.2}, {0.2, 0.5, 0.06, 0.15}});
  for (const NoiseModel truth : {NoiseModel{4e-6, 2e-4}, NoiseModel{2.5e-5, 1e-3}}) {
    const SimField sim = render_field(dome_stage(150, 48, 1.8), scene, truth, 5);
    const std::optional<DataNoise> found = noise_from_data(sim.field, NormalOptions{});
    ASSERT_TRUE(found.has_value());
    std::cout << "truth a " << truth.a << " b " << truth.b << ": found a " << found->model.a
              << " b " << found->model.b << " (" << found->describe() << ")\n";
    EXPECT_NEAR(found->model.a / truth.a, 1.0, 0.15);
    EXPECT_NEAR(found->model.b / truth.b, 1.0, 0.15);
  }
  // The demo scene: glossy and rough spheres, cast shadows, checker edges. The shot term is found
  // as on the matte scene; the read floor, set by the dimmest samples, where what the Lambertian
  // model misses is largest next to the noise, comes out above the truth (measured 3.8x): never
  // below it, so weights are never overconfident.
  const NoiseModel truth{4e-6, 2e-4};
  const SimField demo = render_field(dome_stage(150, 64, 2.4), sim::default_scene(), truth, 5);
  const std::optional<DataNoise> found = noise_from_data(demo.field, NormalOptions{});
  ASSERT_TRUE(found.has_value());
  std::cout << "demo scene: found a " << found->model.a << " b " << found->model.b << "\n";
  EXPECT_GE(found->model.a / truth.a, 1.0);
  EXPECT_LE(found->model.a / truth.a, 4.5);
  EXPECT_NEAR(found->model.b / truth.b, 1.0, 0.15);
  const capture::ReflectanceField tiny = render_field(dome_stage(150, 8, 1.8), scene, {}, 5).field;
  EXPECT_FALSE(noise_from_data(tiny, NormalOptions{}).has_value()) << "64 pixels: too few";
}

TEST(EstimateNormals, RobustSurvivesHighlightsAndCastShadows) {
  physics::brdf::Material glossy;
  glossy.albedo = {0.5, 0.45, 0.4};
  glossy.specular = physics::brdf::SpecularModel::kTorranceSparrow;
  glossy.ks = {0.5, 0.5, 0.5};
  glossy.roughness = 0.15;
  const sim::Scene scene = bumpy_scene(
      glossy, {{-0.45, 0.4, 0.4, 0.15}, {0.4, 0.35, 0.35, 0.12}, {0.0, -0.4, 0.45, 0.18}});
  const NoiseModel noise;
  const SimField sim = render_field(dome_stage(150, 48, 1.8), scene, noise, 11);

  NormalOptions options;
  options.noise = noise;
  options.method = NormalMethod::kLeastSquares;
  const AngularError plain = normal_error(estimate_normals(sim.field, options), sim.hits);
  options.method = NormalMethod::kRobust;
  const NormalMap robust_map = estimate_normals(sim.field, options);
  const AngularError robust = normal_error(robust_map, sim.hits);
  std::cout << "glossy bumps: least squares " << plain.mean_deg << " deg, robust "
            << robust.mean_deg << " deg over " << robust.pixels << " pixels (" << robust.flagged
            << " flagged)\n";
  // Measured: least squares 9.2 deg, robust 0.57 deg (seed 11); the bounds leave room both ways.
  EXPECT_GT(plain.mean_deg, 3.0);
  EXPECT_LT(robust.mean_deg, 3.0);
  EXPECT_LE(robust.flagged, robust.pixels / 100);
  expect_finite(robust_map.normal);
}

TEST(EstimateNormals, TwoValidLightsAreFlaggedNeverNaN) {
  physics::brdf::Material matte;
  const sim::Scene scene = bumpy_scene(matte, {{0, 0, 0.1, 0.3}});
  SimField sim = render_field(dome_stage(24, 16, 1.8), scene, NoiseModel{}, 3);
  for (int l = 2; l < sim.field.num_lights(); ++l) sim.field.lights()[l].valid = false;
  const NormalMap map = estimate_normals(sim.field, NormalOptions{});
  EXPECT_EQ(map.flagged_pixels, 16 * 16);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) {
      const int flags = int(map.flags.at(x, y, 0));
      EXPECT_TRUE(flags & (kTooFewLights | kAllShadowed)) << x << "," << y << ": " << flags;
      EXPECT_EQ(map.confidence.at(x, y, 0), 0.0f);
    }
  }
  expect_finite(map.normal);
  expect_finite(map.albedo);
}

TEST(EstimateNormals, LightsInOnePlaneAreIllConditioned) {
  // All LEDs on one great circle: the component of n normal to that plane is unobservable.
  std::vector<Eigen::Vector3d> dirs;
  for (int i = 0; i < 12; ++i) {
    const double a = 0.2 + 2.7 * i / 11;
    dirs.emplace_back(std::cos(a), std::sin(a), 0.0);
  }
  Stage stage = stage_with_directions(dirs);
  stage.camera.width = stage.camera.height = 8;
  stage.camera.ortho_height_m = 1.0;
  physics::brdf::Material matte;
  const SimField sim = render_field(stage, bumpy_scene(matte, {{0, 0, 0.1, 0.3}}), NoiseModel{}, 5);
  const NormalMap map = estimate_normals(sim.field, NormalOptions{});
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) EXPECT_NE(int(map.flags.at(x, y, 0)), 0) << x << "," << y;
  }
  expect_finite(map.normal);
}

TEST(EstimateNormals, RejectsInvalidOptions) {
  NormalOptions options;
  options.min_lights = 2;
  EXPECT_NE(options.validate().find("min_lights"), std::string::npos);
  EXPECT_THROW(estimate_normals(capture::ReflectanceField(), options), InputError);
}

}  // namespace
}  // namespace ls::relight
