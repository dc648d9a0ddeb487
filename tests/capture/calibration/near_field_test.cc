// Near-field LEDs at build and in the fits: a dome of LEDs 0.8 m from a gently bumpy surface that
// spans +-0.3 m, so that each pixel sees every LED from its own direction (up to 20 deg apart) and
// distance. Built as near LEDs (positions, per-pixel distance and direction) and as the distant
// LEDs a far-field build assumes, from the same simulated photographs.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "capture/build_field.h"
#include "capture/field.h"
#include "capture/field_file.h"
#include "capture/light_calibration.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/session.h"
#include "relight/fit/fit.h"
#include "relight/fit/normals.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
#include "tests/support/instant_sequencer.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

constexpr int kImageSize = 64;
constexpr double kDomeRadiusM = 0.8;

// 60 LEDs over the hemisphere in front of the surface (toward the camera, +Z), above 15 deg.
Stage near_stage() {
  std::vector<Eigen::Vector3d> dirs;
  for (const Eigen::Vector3d& d : fibonacci_dome_directions(60, 15.0)) {
    dirs.push_back(Eigen::Vector3d(d.x(), -d.z(), d.y()));  // The dome's pole from +Y to +Z.
  }
  Stage stage = stage_with_directions(dirs);
  for (Led& led : stage.leds) led.distance_m = kDomeRadiusM;
  stage.camera.width = stage.camera.height = kImageSize;
  stage.camera.ortho_height_m = 0.7;
  return stage;
}

// A matte height field around z = 0 with bumps of 4 cm.
sim::Scene bumpy_surface() {
  return sim::parse_scene(R"json({
    "materials": [{"name": "matte", "diffuse": "lambert", "albedo": [0.7, 0.6, 0.5]}],
    "height_fields": [
      {"center": [0, 0, 0], "half_width": 0.3, "half_height": 0.3, "resolution": 128,
       "material": "matte",
       "procedural": {"bumps": [{"x": -0.1, "y": 0.08, "height": 0.04, "width": 0.1},
                                {"x": 0.12, "y": -0.1, "height": 0.03, "width": 0.08}]}}
    ]})json",
                          "<bumpy>");
}

struct AngleError {
  double mean_deg = 0, worst_deg = 0;
  int pixels = 0;
};

// Normals (3 channels at `channel`, stage frame) against the simulator's surface normals, over the
// surface pixels where every map in `all` has one.
AngleError normal_error(const Image& normals, int channel, const std::vector<sim::SurfaceHit>& hits,
                        const std::vector<const Image*>& all) {
  AngleError e;
  for (const sim::SurfaceHit& h : hits) {
    if (!h.hit) continue;
    bool everywhere = true;
    for (const Image* m : all) everywhere &= m->at(h.pixel_x, h.pixel_y, channel + 2) != 0;
    if (!everywhere) continue;
    const Eigen::Vector3d n(normals.at(h.pixel_x, h.pixel_y, channel),
                            normals.at(h.pixel_x, h.pixel_y, channel + 1),
                            normals.at(h.pixel_x, h.pixel_y, channel + 2));
    const double deg = capture::angle_between_deg(n, h.normal);
    e.mean_deg += deg;
    e.worst_deg = std::max(e.worst_deg, deg);
    ++e.pixels;
  }
  e.mean_deg /= std::max(e.pixels, 1);
  return e;
}

relight::NoiseModel noise_of(const capture::ReflectanceField& field) {
  relight::NoiseModel noise;
  if (field.noise.measured) {
    noise.a = field.noise.read_variance;
    noise.b = field.noise.shot_variance_per_unit;
  }
  return noise;
}

TEST(NearField, PerPixelDirectionsAndDistancesGiveTheNormals) {
  testing::TempDir dir;
  const Stage stage = near_stage();
  Stage distant = stage;  // The same LEDs, taken to be at infinity.
  for (Led& led : distant.leds) led.distance_m.reset();
  sim::SimStage sim(stage, bumpy_surface(), /*seed=*/3);
  Session near_session = Session::create(dir / "near", stage, {});
  run_capture(near_session, sim.lights(), sim.camera(), ls::testing::instant_sequencer());
  Session far_session = Session::create(dir / "far", distant, {});
  run_capture(far_session, sim.lights(), sim.camera(), ls::testing::instant_sequencer());
  capture::BuildSummary summary;
  const capture::ReflectanceField near_field = capture::build_field(near_session, {}, &summary);
  const capture::ReflectanceField far_field = capture::build_field(far_session, {});
  EXPECT_EQ(summary.near_lights, 60);
  ASSERT_TRUE(near_field.lights()[7].position_in_stage);
  EXPECT_NEAR(near_field.lights()[7].position_in_stage->norm(), kDomeRadiusM, 1e-9);
  EXPECT_FALSE(far_field.lights()[7].position_in_stage);

  // Positions and view survive the file; directions per pixel point from the reference point.
  capture::write_field(dir / "near.exr", near_field);
  const capture::ReflectanceField reread = capture::read_field(dir / "near.exr");
  ASSERT_TRUE(reread.view);
  ASSERT_TRUE(reread.lights()[7].position_in_stage);
  EXPECT_LT(
      (*reread.lights()[7].position_in_stage - *near_field.lights()[7].position_in_stage).norm(),
      1e-12);
  const Eigen::Vector3d corner =
      capture::reference_point(*reread.view, kImageSize, kImageSize, 0, 0);
  EXPECT_NEAR(corner.x(), -0.35 + 0.35 / kImageSize, 1e-12);
  EXPECT_NEAR(corner.y(), 0.35 - 0.35 / kImageSize, 1e-12);
  EXPECT_NEAR(corner.z(), 0.0, 1e-12);
  EXPECT_LT((capture::PixelLightDirs(reread, 0, 0)(7) -
             (*reread.lights()[7].position_in_stage - corner).normalized())
                .norm(),
            1e-12);
  EXPECT_LT(
      (capture::PixelLightDirs(far_field, 0, 0)(7) - far_field.lights()[7].dir_in_stage).norm(),
      1e-12);

  relight::NormalOptions options;
  options.noise = noise_of(near_field);
  const relight::NormalMap near_normals = relight::estimate_normals(reread, options);
  options.noise = noise_of(far_field);
  const relight::NormalMap far_normals = relight::estimate_normals(far_field, options);
  const std::vector<const Image*> both = {&near_normals.normal, &far_normals.normal};
  const AngleError near_err = normal_error(near_normals.normal, 0, sim.hits(), both);
  const AngleError far_err = normal_error(far_normals.normal, 0, sim.hits(), both);

  relight::FitOptions fit;
  fit.normals.noise = noise_of(near_field);
  fit.fit_torrance_sparrow = false;  // A matte surface: the normals are what is compared.
  const relight::ModelMaps near_fit = relight::fit_models(reread, near_normals, fit);
  const relight::ModelMaps far_fit = relight::fit_models(far_field, far_normals, fit);
  const std::vector<const Image*> both_fits = {&near_fit.maps, &far_fit.maps};
  const AngleError near_fit_err =
      normal_error(near_fit.maps, relight::kMapNormalX, sim.hits(), both_fits);
  const AngleError far_fit_err =
      normal_error(far_fit.maps, relight::kMapNormalX, sim.hits(), both_fits);
  std::printf(
      "LEDs at %.1f m, surface +-0.3 m, %d pixels: photometric-stereo normals mean %.2f deg "
      "(worst %.2f) as distant LEDs -> %.3f deg (worst %.2f) with positions; fitted models %.2f "
      "(worst %.2f) -> %.3f deg (worst %.2f)\n",
      kDomeRadiusM, near_err.pixels, far_err.mean_deg, far_err.worst_deg, near_err.mean_deg,
      near_err.worst_deg, far_fit_err.mean_deg, far_fit_err.worst_deg, near_fit_err.mean_deg,
      near_fit_err.worst_deg);
  // Measured: 2916 pixels; photometric stereo 17.82 deg mean (worst 26.36) as distant LEDs ->
  // 0.486 deg (worst 2.04) with positions; fitted models 21.86 (42.43) -> 0.606 (2.87). As distant
  // LEDs, the (d0 / r)^2 falloff across the surface (0.39x to 1.9x) tilts every normal toward the
  // near side. What remains is the reference plane: the bumps stand up to 4 cm off z = 0.
  EXPECT_GT(near_err.pixels, 2500);
  EXPECT_GT(far_err.mean_deg, 8.0);
  EXPECT_LT(near_err.mean_deg, 0.8);
  EXPECT_LT(near_err.worst_deg, 3.5);
  EXPECT_GT(far_fit_err.mean_deg, 8.0);
  EXPECT_LT(near_fit_err.mean_deg, 0.9);
}

}  // namespace
}  // namespace ls
