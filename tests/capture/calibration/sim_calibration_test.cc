// Light calibration on targets rendered by the simulator under a deliberately perturbed dome:
// every estimate is compared with the truth the simulator used. The sensor is realistic (optical
// blur, shot and read noise, 12 bits, highlights clipped).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "capture/field.h"
#include "capture/light_calibration.h"
#include "lightstage/image_metrics.h"
#include "physics/envmap.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/calibration_targets.h"
#include "sim/ground_truth.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
#include "tests/capture/calibration/perturbed_dome.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

using capture::angle_between_deg;
// The targets, their photographs and the perturbed dome (shared with calibrated_fit_test.cc).
using testing::balls;
using testing::calibrate;
using testing::calibrate_white;
using testing::distant_dome;
using testing::DistantDome;
using testing::field_for;
using testing::kWhiteFullScale;
using testing::shoot_spheres;
using testing::SphereShots;
using testing::target_camera;

TEST(MirrorSphereSim, OutlinesFoundWithSubPixelAccuracy) {
  const SphereShots shots = shoot_spheres(Stage{}, 7);
  ASSERT_EQ(shots.outlines.size(), 2u);
  for (int s = 0; s < 2; ++s) {
    const double centre_err = (shots.spheres[s].center_in_stage - balls()[s].center).norm();
    const double radius_err = std::abs(shots.spheres[s].radius_m - balls()[s].radius_m);
    std::printf("ball %d: centre off by %.3f mm, radius by %.3f mm (1 px = 0.94 mm)\n", s,
                1e3 * centre_err, 1e3 * radius_err);
    // Measured: centre 0.008 and 0.006 mm, radius 0.012 and 0.020 mm.
    EXPECT_LT(centre_err, 0.1e-3);
    EXPECT_LT(radius_err, 0.1e-3);
  }
}

// The LED's highlight sits at the normal halfway between the LED and the view direction (+Z);
// past about 60 deg it is foreshortened into a thin arc at the rim and may be refused.
double true_normal_angle_deg(const Led& led) {
  return 0.5 * angle_between_deg(led.dir_in_stage, Eigen::Vector3d(0, 0, 1));
}

TEST(MirrorSphereSim, DirectionsOfDistantLedsWithinAFifthOfADegree) {
  const DistantDome& dome = distant_dome();
  ASSERT_EQ(dome.shots.spheres.size(), 2u);
  const capture::DirectionCalibration& cal = dome.directions;
  double worst = 0, rms = 0, nominal_rms = 0;
  int ok = 0;
  for (size_t l = 0; l < cal.leds.size(); ++l) {
    const Led& truth = dome.perturbed.truth.leds[l];
    nominal_rms +=
        std::pow(angle_between_deg(dome.nominal.leds[l].dir_in_stage, truth.dir_in_stage), 2);
    if (!cal.leds[l].ok) {
      EXPECT_GT(true_normal_angle_deg(truth), 60.0) << "LED " << l << " refused";
      continue;
    }
    ++ok;
    const double err = angle_between_deg(cal.leds[l].dir_in_stage, truth.dir_in_stage);
    worst = std::max(worst, err);
    rms += err * err;
    EXPECT_FALSE(cal.leds[l].position_in_stage) << "distant LED " << l << " given a position";
  }
  rms = std::sqrt(rms / std::max(ok, 1));
  nominal_rms = std::sqrt(nominal_rms / double(cal.leds.size()));
  std::printf(
      "%d of %zu LEDs calibrated (%zu sphere images refused, all rim LEDs); error RMS %.4f "
      "deg, worst %.4f deg; the drawing was off by %.3f deg RMS\n",
      ok, cal.leds.size(), cal.problems.size(), rms, worst, nominal_rms);
  for (const auto& p : cal.problems) {
    const Led& truth = dome.perturbed.truth.leds[p.led_index];
    EXPECT_GT(true_normal_angle_deg(truth), 60.0)
        << p.image << " sphere " << p.sphere << ": " << p.what;
  }
  // Measured: 134 of 151 (the 17 behind the balls), RMS 0.034 deg, worst 0.127 deg.
  EXPECT_GE(ok, 130);
  EXPECT_LT(worst, 0.2);
  EXPECT_LT(rms, 0.06);
}

// The same balls seen through a pinhole (CameraSpec fov_y_deg > 0) 1.5 m away with a 12 deg
// vertical field of view (0.32 m high at the balls, about the orthographic view): the outlines
// are ellipses whose centres are not the projected ball centres, and every pixel's ray has its
// own direction, which the calibration's pinhole path must get right.
CameraSpec perspective_target_camera() {
  CameraSpec c = target_camera();
  c.fov_y_deg = 12.0;
  c.distance_m = 1.5;
  return c;
}

TEST(MirrorSphereSim, PerspectiveCameraDirectionsOfDistantLeds) {
  const CameraSpec camera = perspective_target_camera();
  sim::StagePerturbation perturbation;
  perturbation.seed = 11;  // The dome of the orthographic tests.
  const sim::PerturbedStage perturbed = sim::perturb_stage(default_stage(), perturbation);
  const SphereShots shots = shoot_spheres(perturbed.truth, 500, camera);
  ASSERT_EQ(shots.spheres.size(), 2u);
  double worst_centre = 0;
  for (int s = 0; s < 2; ++s) {
    worst_centre =
        std::max(worst_centre, (shots.spheres[s].center_in_stage - balls()[s].center).norm());
  }
  struct Errors {
    int ok = 0;
    double rms = 0, worst = 0;
  };
  auto errors_of = [&](const capture::DirectionCalibration& cal) {
    Errors e;
    for (size_t l = 0; l < cal.leds.size(); ++l) {
      const Led& truth = perturbed.truth.leds[l];
      if (!cal.leds[l].ok) {
        // The view rays fan out by up to 8 deg, so the rim cut-off moves by up to half of that.
        EXPECT_GT(true_normal_angle_deg(truth), 56.0) << "LED " << l << " refused";
        continue;
      }
      ++e.ok;
      const double err = angle_between_deg(cal.leds[l].dir_in_stage, truth.dir_in_stage);
      e.worst = std::max(e.worst, err);
      e.rms += err * err;
    }
    e.rms = std::sqrt(e.rms / std::max(e.ok, 1));
    return e;
  };
  const Errors fitted = errors_of(calibrate(shots, camera));
  SphereShots placed = shots;  // The balls where they truly are: the highlights' share alone.
  for (int s = 0; s < 2; ++s) placed.spheres[s].center_in_stage = balls()[s].center;
  const Errors highlights = errors_of(calibrate(placed, camera));
  std::printf(
      "perspective: balls located within %.3f mm; %d of %zu LEDs calibrated, error RMS %.4f deg, "
      "worst %.4f deg; with the true ball centres RMS %.4f, worst %.4f deg\n",
      1e3 * worst_centre, fitted.ok, shots.images.size(), fitted.rms, fitted.worst, highlights.rms,
      highlights.worst);
  // Measured: balls within 0.431 mm (mostly depth: the tangent cone's half angle is 0.067 rad,
  // so a 0.02 px error in the outline's major axis moves the ball 0.4 mm along the view ray;
  // orthographic views take the depth as given); 136 of 151 LEDs, RMS 0.069 deg, worst 0.284 deg.
  // With the true centres: RMS 0.035, worst 0.189 deg, as orthographic (0.034, 0.127). So the
  // pinhole path meets the 0.2 deg target; a ball placed from its outline alone does not quite:
  // measure its distance (or use the two balls' known spacing) where 0.2 deg is needed.
  EXPECT_LT(worst_centre, 0.7e-3);
  EXPECT_GE(fitted.ok, 130);
  EXPECT_LT(fitted.worst, 0.35);
  EXPECT_LT(fitted.rms, 0.09);
  EXPECT_LT(highlights.worst, 0.22);
  EXPECT_LT(highlights.rms, 0.05);
}

TEST(MirrorSphereSim, PositionsOfNearLedsWithinOnePercentOfTheDomeRadius) {
  const Stage nominal = stage_with_directions(fibonacci_dome_directions(60, 0.0));
  sim::StagePerturbation perturbation;
  perturbation.seed = 23;
  perturbation.dome_radius_m = 1.0;
  const sim::PerturbedStage perturbed = sim::perturb_stage(nominal, perturbation);
  const SphereShots shots = shoot_spheres(perturbed.truth, 300);
  ASSERT_EQ(shots.spheres.size(), 2u);
  const capture::DirectionCalibration cal = calibrate(shots);
  double worst_pos = 0, worst_dir = 0;
  int positioned = 0;
  for (size_t l = 0; l < cal.leds.size(); ++l) {
    const Led& truth = perturbed.truth.leds[l];
    if (!cal.leds[l].ok) {
      EXPECT_GT(true_normal_angle_deg(truth), 60.0) << "LED " << l << " refused";
      continue;
    }
    if (!cal.leds[l].position_in_stage) continue;  // Seen by one ball only.
    ++positioned;
    const Eigen::Vector3d truth_pos = *truth.distance_m * truth.dir_in_stage;
    worst_pos = std::max(worst_pos, (*cal.leds[l].position_in_stage - truth_pos).norm());
    worst_dir =
        std::max(worst_dir, angle_between_deg(cal.leds[l].dir_in_stage, truth.dir_in_stage));
  }
  std::printf(
      "%d of %zu near LEDs triangulated: worst position error %.2f mm (dome radius 1 m), "
      "worst direction %.3f deg\n",
      positioned, cal.leds.size(), 1e3 * worst_pos, worst_dir);
  // Measured: 36 of 60 (the others cross at under 10 deg, along the line through the balls, or
  // leave a ball near its rim), worst 5.6 mm = 0.56% of the radius, direction 0.057 deg.
  EXPECT_GE(positioned, 33);
  EXPECT_LT(worst_pos, 0.008);
  EXPECT_LT(worst_dir, 0.1);
}

TEST(WhiteTargetSim, IntensitiesAndColoursWithinOnePercent) {
  const DistantDome& dome = distant_dome();
  double worst = 0, worst_flat = 0, nominal_worst = 0;
  int ok = 0;
  for (const auto& est : dome.intensities.leds) {
    const Led& truth = dome.perturbed.truth.leds[est.led_index];
    if (!est.ok) {
      // A plane facing the camera is not lit from behind or from grazing angles.
      EXPECT_LT(truth.dir_in_stage.z(), 0.2) << "LED " << est.led_index << " refused";
      continue;
    }
    ++ok;
    const Eigen::Vector3d t = truth.irradiance_rgb();
    for (int c = 0; c < 3; ++c) {
      worst = std::max(worst, std::abs(est.irradiance_rgb[c] / t[c] - 1.0));
      nominal_worst = std::max(
          nominal_worst, std::abs(dome.nominal.leds[est.led_index].irradiance_rgb()[c] / t[c] - 1));
    }
    // The flat field against the beam, at the corners of the view (x = -+0.3 m, y = -+0.15 m).
    const sim::LedBeam& beam = dome.perturbed.beams[est.led_index];
    for (double u : {-0.9, 0.9}) {
      for (double v : {-0.9, 0.9}) {
        const double x = 0.3 * u, y = -0.15 * v;
        worst_flat = std::max(worst_flat, std::abs(est.flat_field.at(u, v) / beam.at(x, y) - 1));
      }
    }
  }
  std::printf(
      "%d of %zu LEDs: worst irradiance error %.3f%% per channel (the drawing: %.1f%%), "
      "worst flat-field error %.3f%%; %zu refused\n",
      ok, dome.intensities.leds.size(), 100 * worst, 100 * nominal_worst, 100 * worst_flat,
      dome.intensities.problems.size());
  // Measured: 70 of 151 (a plane facing the camera sees only the front of the dome), worst 0.74%
  // (the drawing: 17.3%), flat field 0.08%.
  EXPECT_GE(ok, 65);
  EXPECT_LT(worst, 0.01);
  EXPECT_LT(worst_flat, 0.01);
}

TEST(CalibrationSim, BadImagesAreReportedAndTheOthersStillUsed) {
  const DistantDome& dome = distant_dome();
  // LED 0 off (no highlight), LEDs 1 and 2 both on, LED 3's image the wrong size.
  std::vector<Image> images(dome.shots.images.begin(), dome.shots.images.begin() + 10);
  std::fill(images[0].pixels.begin(), images[0].pixels.end(), 0.0f);
  for (size_t i = 0; i < images[1].pixels.size(); ++i) {
    images[1].pixels[i] = std::max(images[1].pixels[i], dome.shots.images[140].pixels[i]);
  }
  images[3] = Image(32, 32, 3);
  SphereShots shots = dome.shots;
  shots.images = images;
  const capture::DirectionCalibration cal = calibrate(shots);
  auto problem_of = [&](int led) {
    std::string all;
    for (const auto& p : cal.problems) {
      if (p.led_index == led) all += p.what + "; ";
    }
    return all;
  };
  EXPECT_NE(problem_of(0).find("no highlight"), std::string::npos) << problem_of(0);
  EXPECT_NE(problem_of(1).find("two highlights"), std::string::npos) << problem_of(1);
  EXPECT_NE(problem_of(3).find("image is 32x32"), std::string::npos) << problem_of(3);
  EXPECT_FALSE(cal.leds[0].ok);
  EXPECT_FALSE(cal.leds[3].ok);
  for (int l : {4, 5, 6, 7, 8, 9}) {
    EXPECT_EQ(cal.leds[l].ok, dome.directions.leds[l].ok) << l;
  }
  // No sphere in a black reference shot.
  EXPECT_TRUE(capture::find_sphere_outlines(Image(64, 64, 3), 2).empty());
  // A white target exposed too long: refused, the rest used.
  std::vector<Image> white = dome.white;
  for (float& v : white[5].pixels) v = std::min(v * 20.0f, float(kWhiteFullScale));
  const capture::IntensityCalibration ic = calibrate_white(white, dome.calibrated);
  ASSERT_FALSE(ic.problems.empty());
  bool saturated_reported = false;
  for (const auto& p : ic.problems) {
    if (p.led_index == 5) saturated_reported = p.what.find("saturated") != std::string::npos;
  }
  EXPECT_TRUE(saturated_reported);
  EXPECT_FALSE(ic.leds[5].ok);
  EXPECT_TRUE(ic.leds[6].ok == dome.intensities.leds[6].ok);
}

TEST(CalibrationSim, RelightingWithTheCalibratedStageBeatsTheDrawing) {
  const DistantDome& dome = distant_dome();
  Stage truth = dome.perturbed.truth;
  truth.camera.width = truth.camera.height = 64;
  sim::SimStage sim_stage(truth, sim::default_scene(), /*seed=*/5);
  const capture::ReflectanceField nominal_field = field_for(sim_stage, truth, dome.nominal);
  const capture::ReflectanceField calibrated_field = field_for(sim_stage, truth, dome.calibrated);
  for (const char* name : {"sky_sun.exr", "softbox_studio.exr"}) {
    const physics::EnvironmentMap map =
        physics::EnvironmentMap::load(testing::source_dir() / "data" / "envmaps" / name);
    sim::GroundTruthOptions gt;
    gt.directions_width = 128;
    gt.covered_by_leds = truth.led_directions();
    const Image reference = sim::render_ground_truth(sim_stage.scene(), truth.camera, map, gt);
    auto error_with = [&](const capture::ReflectanceField& field, const Stage& stage) {
      const relight::LightWeights w =
          relight::integrate_environment(map, stage.led_directions(), 0.0);
      return compare_images(relight::relight(field, w), reference).relative_rmse;
    };
    const double nominal_err = error_with(nominal_field, dome.nominal);
    const double calibrated_err = error_with(calibrated_field, dome.calibrated);
    const double truth_err = error_with(field_for(sim_stage, truth, truth), truth);
    std::printf(
        "%s: relative RMSE vs ground truth: nominal stage %.4f, calibrated %.4f, true "
        "stage %.4f\n",
        name, nominal_err, calibrated_err, truth_err);
    // Measured: sky_sun 0.1320 -> 0.0954 (true stage 0.0953); softbox_studio 0.0482 -> 0.0444
    // (0.0430): what calibration can remove, it removes (100% and 73%; the rest is the rear LEDs,
    // whose intensities a camera-facing white plane cannot see).
    EXPECT_LT(calibrated_err, nominal_err);
    EXPECT_LT(calibrated_err - truth_err, 0.4 * (nominal_err - truth_err));
  }
}

}  // namespace
}  // namespace ls
