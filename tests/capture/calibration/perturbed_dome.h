#pragma once
// The perturbed simulated dome of the calibration tests: the built-in dome as drawn, the dome as
// built (sim::perturb_stage, seed 11), photographed (mirror spheres, white target) and calibrated
// as `lightstage calibrate` does, so that tests can compare drawn, calibrated and true stages.
#include <memory>
#include <string>
#include <vector>

#include "capture/field.h"
#include "capture/light_calibration.h"
#include "sim/calibration_targets.h"
#include "sim/sim_stage.h"

namespace ls::testing {

// 640 x 320 orthographic view of two mirror balls of radius 0.1 m at x = -+0.18 m (107 px each),
// and of a white plane at z = 0 filling the view.
inline CameraSpec target_camera() {
  CameraSpec c = default_stage().camera;
  c.width = 640;
  c.height = 320;
  c.fov_y_deg = 0;
  c.ortho_height_m = 0.3;
  return c;
}

inline std::vector<sim::MirrorBall> balls() {
  return {{Eigen::Vector3d(-0.18, 0, 0), 0.1}, {Eigen::Vector3d(0.18, 0, 0), 0.1}};
}

constexpr double kLedRadiusM = 0.025;  // A diffused LED, 5 cm across, at 1 m: 1.4 deg radius.
constexpr double kChrome = 0.65;

struct SphereShots {
  std::vector<Image> images;
  std::vector<capture::SphereOutline> outlines;
  std::vector<capture::MirrorSphere> spheres;
};

// Renders every LED's mirror-ball photograph, exposed so that the highlights clip (a real
// calibration exposes for the dim ones), then fits the ball outlines from the reference shot.
inline SphereShots shoot_spheres(const Stage& truth, uint64_t seed,
                                 const CameraSpec& camera = target_camera()) {
  const sim::MirrorSphereRenderer renderer(balls(), camera, /*supersample=*/8);
  SphereShots shots;
  sim::SensorModel sensor;
  sensor.full_scale = 2.0;
  const Image reference = sim::apply_sensor(
      renderer.render_reference(/*environment_radiance=*/1.0, kChrome), sensor, seed);
  shots.outlines = capture::find_sphere_outlines(reference, /*max_spheres=*/2);
  const capture::ViewCamera view = capture::ViewCamera::from_spec(camera);
  for (const auto& o : shots.outlines) {
    shots.spheres.push_back(capture::locate_sphere(o, view, /*radius_m=*/0.1));
  }
  // LED radiance is E / solid angle, about 500 E at 1.4 deg: full scale at 100 E clips the core.
  sensor.full_scale = 100.0;
  for (size_t l = 0; l < truth.leds.size(); ++l) {
    shots.images.push_back(sim::apply_sensor(
        renderer.render_led(truth.leds[l], kLedRadiusM, kChrome), sensor, seed + 1 + l));
  }
  return shots;
}

inline capture::DirectionCalibration calibrate(const SphereShots& shots,
                                               const CameraSpec& camera = target_camera()) {
  std::vector<const Image*> images;
  std::vector<std::string> names;
  for (size_t i = 0; i < shots.images.size(); ++i) {
    images.push_back(&shots.images[i]);
    names.push_back("led" + std::to_string(i));
  }
  capture::DirectionOptions options;
  options.highlight.saturation_level = 100.0;
  return capture::calibrate_directions(images, names, shots.outlines, shots.spheres,
                                       capture::ViewCamera::from_spec(camera), options);
}

// The perturbed built-in dome (distant LEDs), photographed once for all the tests below.
struct DistantDome {
  Stage nominal = default_stage();
  sim::PerturbedStage perturbed;
  SphereShots shots;
  capture::DirectionCalibration directions;
  Stage calibrated;  // Nominal, with the calibrated directions and then intensities.
  capture::IntensityCalibration intensities;
  std::vector<Image> white;
};

constexpr double kAlbedo = 0.8;
constexpr double kWhiteFullScale = 0.5;  // The brightest LED reads about 70% of full scale.

inline std::vector<Image> shoot_white(const sim::PerturbedStage& perturbed, uint64_t seed) {
  std::vector<Image> out;
  sim::SensorModel sensor;
  sensor.full_scale = kWhiteFullScale;
  sim::WhitePlaneTarget plane;
  plane.albedo = kAlbedo;
  for (size_t l = 0; l < perturbed.truth.leds.size(); ++l) {
    out.push_back(sim::apply_sensor(sim::render_white_plane(plane, perturbed.truth.leds[l],
                                                            perturbed.beams[l], target_camera()),
                                    sensor, seed + l));
  }
  return out;
}

inline capture::IntensityCalibration calibrate_white(const std::vector<Image>& white,
                                                     const Stage& stage) {
  std::vector<const Image*> images;
  std::vector<std::string> names;
  for (size_t i = 0; i < white.size(); ++i) {
    images.push_back(&white[i]);
    names.push_back("white" + std::to_string(i));
  }
  capture::WhitePlane plane;
  plane.albedo = kAlbedo;
  capture::IntensityOptions options;
  options.saturation_level = kWhiteFullScale;
  return capture::calibrate_intensities(images, names, stage, plane,
                                        capture::ViewCamera::from_spec(target_camera()), options);
}

inline const DistantDome& distant_dome() {
  static const std::unique_ptr<DistantDome> dome = [] {
    auto d = std::make_unique<DistantDome>();
    sim::StagePerturbation perturbation;
    perturbation.seed = 11;
    d->perturbed = sim::perturb_stage(d->nominal, perturbation);
    d->shots = shoot_spheres(d->perturbed.truth, 100);
    d->directions = calibrate(d->shots);
    d->calibrated = d->nominal;
    capture::apply_directions(d->directions, &d->calibrated);
    d->white = shoot_white(d->perturbed, 1000);
    d->intensities = calibrate_white(d->white, d->calibrated);
    capture::apply_intensities(d->intensities, &d->calibrated);
    return d;
  }();
  return *dome;
}

// The field build_field would produce for a stage file S from a capture on the true dome:
// R_S(x, l) = R_true(x, l) * E_true,l / E_S,l per channel, with S's LED directions.
inline capture::ReflectanceField field_for(sim::SimStage& sim_stage, const Stage& truth,
                                           const Stage& file) {
  std::vector<capture::FieldLight> lights;
  for (const Led& led : file.leds) lights.push_back({led.id, led.dir_in_stage, true});
  const CameraSpec& cam = truth.camera;
  capture::ReflectanceField field(cam.width, cam.height, lights);
  for (size_t l = 0; l < truth.leds.size(); ++l) {
    const Image& one = sim_stage.one_light_image(int(l));
    const Eigen::Vector3d ratio =
        truth.leds[l].irradiance_rgb().cwiseQuotient(file.leds[l].irradiance_rgb());
    for (int y = 0; y < cam.height; ++y) {
      for (int x = 0; x < cam.width; ++x) {
        for (int c = 0; c < 3; ++c) field.at(x, y, int(l), c) = float(one.at(x, y, c) * ratio[c]);
      }
    }
  }
  return field;
}

}  // namespace ls::testing
