// Leave-lights-out accuracy of every representation (every 5th LED held out, rebuilt from the rest,
// relit at the held-out directions) on the simulated scenes and the real RTI set, and environment
// relighting against the simulator's ground truth.
// The lower PSNR bounds are regression guards: the measured value (in the comments) less 1 dB, i.e.
// an RMS error 12% above the measured one trips them. Where there is an independent reference it
// is checked as well: on the simulated scenes the held-out images carry the simulated sensor noise,
// which no reconstruction from the other LEDs can predict, so the noise alone bounds PSNR from
// above.
#include "evaluation/leave_lights_out.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/ground_truth.h"
#include "tests/relight/compact/compact_fixtures.h"

namespace ls::evaluation {
namespace {

using sim::GroundTruthOptions;
using sim::render_ground_truth;
using sim::render_noisy_field;
using sim::rti_dome_stage;
using sim::rti_scene;
using sim::RtiScene;

using namespace compact_testing;
using relight::RtiBasis;

struct Bound {
  const char* what;
  CompactBuilder build;
  double min_psnr_db[3];  // matte, glossy, shadowed
};

void print(const char* scene, const LeaveLightsOutResult& r) {
  std::printf("%-9s %-16s PSNR %6.2f dB  SSIM %.4f  %7.1f B/px  build %.2f s\n", scene,
              r.name.c_str(), r.psnr_db, r.ssim, r.bytes_per_pixel, r.build_s);
}

TEST(LeaveLightsOut, SsimIsOneForIdenticalImagesAndDropsWithNoise) {
  Image a(32, 32, 3);
  for (size_t i = 0; i < a.pixels.size(); ++i) a.pixels[i] = float((i * 7919) % 101) / 100;
  EXPECT_NEAR(ssim(a, a, 1.0), 1.0, 1e-12);
  Image b = a;
  for (size_t i = 0; i < b.pixels.size(); ++i) b.pixels[i] += (i % 2 ? 0.1f : -0.1f);
  EXPECT_LT(ssim(b, a, 1.0), 0.97);  // Measured 0.94.
}

// Measured (PSNR dB on held-out LEDs, matte / glossy / shadowed; SSIM in the output):
//   raw field (RBF between LEDs)   21.9 / 37.0 / 22.1      1440 B/px
//   pca k=16                       25.0 / 31.4 / 24.7       194 B/px
//   pca auto (k 86 / 105 / 101)    22.2 / 37.1 / 22.2     ~1200 B/px
//   pca k=16, 16 px tiles          22.8 / 37.3 / 23.6       222 B/px
//   ptm-rgb / ptm-lrgb             20.4 / 26.1 / 21.9    18 / 9 B/px
//   hsh2 / hsh3 / hsh4             20.1 / 25.0 / 21.2, 22.9 / 27.5 / 23.2, 24.4 / 30.2 / 24.4
// The matte and shadowed scenes are limited by cast shadows whose edges move between LEDs: no
// interpolation in the light direction recovers them, and a high rank interpolates the noise of
// the neighbouring LEDs as well (there the automatic k, chosen for the LEDs themselves, is not
// the best for held-out directions).
// The PSNR that the held-out images' own noise allows: peak^2 over the mean noise variance
// (read + shot * value, the simulated sensor's) of the held-out images, with the peak and the
// held-out set as leave_lights_out() takes them.
double noise_floor_psnr_db(const capture::ReflectanceField& field) {
  const LeaveLightsOutOptions options;
  double peak = 0, variance = 0;
  long count = 0;
  for (int l = 0; l < field.num_lights(); ++l) {
    if (l % options.every != options.offset || !field.lights()[l].valid) continue;
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        for (int c = 0; c < 3; ++c) {
          const double v = field.at(x, y, l, c);
          peak = std::max(peak, v);
          variance +=
              field.noise.read_variance + field.noise.shot_variance_per_unit * std::max(v, 0.0);
          ++count;
        }
      }
    }
  }
  return 10 * std::log10(peak * peak / (variance / count));
}

TEST(LeaveLightsOut, SimulatedScenesMeetMeasuredBounds) {
  const Bound bounds[] = {
      {"raw", raw_builder(), {21.0, 36.0, 21.0}},
      {"pca16", pca_builder(16), {24.0, 30.4, 23.7}},
      {"pca-auto", pca_builder(0), {21.2, 36.1, 21.2}},
      {"pca16-tile16", pca_builder(16, 16), {21.8, 36.3, 22.6}},
      {"ptm-rgb", rti_builder(RtiBasis::kPtm), {19.4, 25.1, 20.9}},
      {"ptm-lrgb", rti_builder(RtiBasis::kPtm, true), {19.4, 25.1, 20.9}},
      {"hsh2", rti_builder(RtiBasis::kHsh2), {19.1, 24.0, 20.2}},
      {"hsh3", rti_builder(RtiBasis::kHsh3), {21.9, 26.5, 22.2}},
      {"hsh4", rti_builder(RtiBasis::kHsh4), {23.4, 29.2, 23.4}},
  };
  const RtiScene scenes[] = {RtiScene::kMatte, RtiScene::kGlossy, RtiScene::kShadowed};
  for (int s = 0; s < 3; ++s) {
    const auto& field = sim_field(scenes[s]);
    const double floor_db = noise_floor_psnr_db(field);
    std::printf("%-9s noise floor PSNR %6.2f dB\n", to_string(scenes[s]), floor_db);
    for (const Bound& b : bounds) {
      const auto r = leave_lights_out(field, b.build);
      print(to_string(scenes[s]), r);
      EXPECT_GT(r.psnr_db, b.min_psnr_db[s]) << b.what << " on " << to_string(scenes[s]);
      // Independent of any measurement: a held-out image's noise cannot be reconstructed, so
      // its mean squared error is at least the noise variance (0.1 dB: the sample variance of
      // ~370000 values and the shot term taken at the noisy value).
      EXPECT_LT(r.psnr_db, floor_db + 0.1) << b.what << " on " << to_string(scenes[s]);
      EXPECT_GT(r.ssim, 0.35);  // Lowest measured: raw field on the shadowed scene, 0.39.
    }
  }
}

TEST(LeaveLightsOut, FittedModelsOnASmallGlossyScene) {
  const auto field = render_noisy_field(rti_dome_stage(150, 10.0, 32), rti_scene(RtiScene::kGlossy),
                                        sim_noise(), 3);
  const auto r = leave_lights_out(field, model_builder());
  print("glossy32", r);
  EXPECT_GT(r.psnr_db, 32.2);  // Measured 33.25 dB.
  EXPECT_GT(r.ssim, 0.83);     // Measured 0.858.
}

// The real set (64 x 43 px, 240 lights, 8-bit sRGB JPEGs; noise estimated from the spectrum).
// Measured PSNR: raw 34.65, pca auto (k 136) 34.73, pca k=8 31.05, ptm-rgb 29.86, ptm-lrgb 29.80,
// hsh2 29.41, hsh3 30.99, hsh4 31.88 dB.
TEST(LeaveLightsOut, RealRtiSetMeetsMeasuredBounds) {
  if (!std::filesystem::exists(real_lp())) GTEST_SKIP() << real_lp() << " is absent";
  const auto& field = real_field();
  const std::pair<CompactBuilder, double> bounds[] = {
      {raw_builder(), 33.6},
      {pca_builder(0), 33.7},
      {pca_builder(8), 30.0},
      {rti_builder(RtiBasis::kPtm), 28.8},
      {rti_builder(RtiBasis::kPtm, true), 28.8},
      {rti_builder(RtiBasis::kHsh2), 28.4},
      {rti_builder(RtiBasis::kHsh3), 30.0},
      {rti_builder(RtiBasis::kHsh4), 30.9},
  };
  for (const auto& [build, min_psnr] : bounds) {
    const auto r = leave_lights_out(field, build);
    print("real", r);
    EXPECT_GT(r.psnr_db, min_psnr) << r.name;
    EXPECT_GT(r.ssim, 0.74) << r.name;  // Lowest measured: hsh2, 0.770.
  }
}

// Environment relighting of the glossy scene under the sun-and-sky map, each representation lit
// by the LED cells' irradiance, against ground truth rendered from the scene (covered directions).
TEST(EnvironmentRelighting, EveryRepresentationAgainstGroundTruth) {
  const RtiScene scene = RtiScene::kGlossy;
  const auto& field = sim_field(scene);
  const Stage stage = rti_dome_stage();
  const auto dirs = stage.led_directions();
  const double coverage = max_nearest_neighbour_angle(dirs);
  const auto map =
      physics::EnvironmentMap::load(testing::source_dir() / "data/envmaps/sky_sun.exr");
  const relight::LightWeights weights = relight::integrate_environment(map, dirs, 0, coverage);
  GroundTruthOptions gt;
  gt.directions_width = 128;
  gt.covered_by_leds = dirs;
  gt.coverage_radius_rad = coverage;
  const Image truth = render_ground_truth(rti_scene(scene), stage.camera, map, gt);
  const auto lights = relight::LightingForModels::led_cells(dirs, weights);
  const ImageError field_error = compare_images(relight::relight(field, weights), truth);
  std::printf("env field: rel %.4f psnr %.2f\n", field_error.relative_rmse, field_error.psnr_db);
  // Measured PSNR (relative RMSE): field 42.86 (4.4%); pca auto 43.15 (4.2%), k=16 34.05 (12%),
  // k=16 in 16 px tiles 42.33 (4.7%); ptm-rgb 28.21, ptm-lrgb 28.04, hsh2 26.58, hsh3 29.16,
  // hsh4 33.34 (13%). The RTI bases cannot hold the glossy highlight under the sun.
  EXPECT_GT(field_error.psnr_db, 41.8);
  const std::pair<CompactBuilder, double> bounds[] = {
      {pca_builder(0), 42.1},
      {pca_builder(16), 33.0},
      {pca_builder(16, 16), 41.3},
      {rti_builder(RtiBasis::kPtm), 27.2},
      {rti_builder(RtiBasis::kPtm, true), 27.0},
      {rti_builder(RtiBasis::kHsh2), 25.6},
      {rti_builder(RtiBasis::kHsh3), 28.1},
      {rti_builder(RtiBasis::kHsh4), 32.3},
  };
  for (const auto& [build, min_psnr] : bounds) {
    const auto compact = build(field);
    const ImageError e = compare_images(compact->relight(lights), truth);
    std::printf("env %-16s rel %.4f psnr %.2f\n", compact->name().c_str(), e.relative_rmse,
                e.psnr_db);
    EXPECT_GT(e.psnr_db, min_psnr) << compact->name();
  }
}

}  // namespace
}  // namespace ls::evaluation
