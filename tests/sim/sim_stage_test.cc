#include "sim/sim_stage.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <numbers>

#include "lightstage/errors.h"
#include "sim/noisy_field.h"
#include "tests/support/test_support.h"

namespace ls::sim {
namespace {

int add_lambert(Scene& scene, const Eigen::Vector3d& albedo) {
  SceneMaterial m;
  m.name = "lambert" + std::to_string(scene.materials.size());
  m.base.albedo = albedo;
  scene.materials.push_back(m);
  return int(scene.materials.size()) - 1;
}

CameraSpec ortho_camera(int size, double view_height_m = 2.4) {
  CameraSpec camera;
  camera.width = camera.height = size;
  camera.fov_y_deg = 0.0;
  camera.ortho_height_m = view_height_m;
  return camera;
}

// World (x, y) of an orthographic pixel centre.
Eigen::Vector2d ortho_pixel_xy(const CameraSpec& camera, int x, int y) {
  const double half = 0.5 * camera.ortho_height_m;
  return {(2.0 * (x + 0.5) / camera.width - 1.0) * half * camera.width / camera.height,
          (1.0 - 2.0 * (y + 0.5) / camera.height) * half};
}

TEST(TraceCamera, LambertSphereUnderOneLightMatchesClosedForm) {
  Scene scene;
  const double albedo = 0.6, radius = 0.5;
  scene.spheres.push_back(
      {{0, 0, 0}, radius, add_lambert(scene, Eigen::Vector3d::Constant(albedo))});
  const CameraSpec camera = ortho_camera(64);
  const auto hits = trace_camera(scene, camera);
  const Eigen::Vector3d light = Eigen::Vector3d(0.6, 0.5, 0.4).normalized();
  const Image image = render_one_light(scene, hits, light);
  ASSERT_EQ(image.width, 64);
  ASSERT_EQ(image.height, 64);
  ASSERT_EQ(image.channels, 3);
  int lit = 0, dark_side = 0, background = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      const Eigen::Vector2d p = ortho_pixel_xy(camera, x, y);
      const double r2 = p.squaredNorm();
      double expected = 0;
      if (r2 < radius * radius) {
        ASSERT_TRUE(hits[y * 64 + x].hit) << x << "," << y;
        const Eigen::Vector3d n(p.x() / radius, p.y() / radius,
                                std::sqrt(1 - r2 / (radius * radius)));
        EXPECT_LT((hits[y * 64 + x].normal - n).norm(), 1e-9);
        const double cos_l = n.dot(light);
        expected = albedo / std::numbers::pi * std::max(0.0, cos_l);
        (cos_l > 0 ? lit : dark_side)++;
      } else {
        EXPECT_FALSE(hits[y * 64 + x].hit) << x << "," << y;
        ++background;
      }
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(image.at(x, y, c), expected, 1e-6) << x << "," << y;
    }
  }
  EXPECT_GT(lit, 300);
  EXPECT_GT(dark_side, 50);
  EXPECT_GT(background, 1000);
}

TEST(TraceCamera, PerspectiveProjectionPutsTheSphereWhereExpected) {
  Scene scene;
  const Eigen::Vector3d center(0.5, 0.3, 0.0);
  scene.spheres.push_back({center, 0.15, add_lambert(scene, Eigen::Vector3d::Constant(0.5))});
  CameraSpec camera;
  camera.width = 160;
  camera.height = 120;
  camera.fov_y_deg = 30;
  camera.distance_m = 4;
  const auto hits = trace_camera(scene, camera);
  // Pinhole at (0, 0, 4): the centre projects to pixel (W/2 + f x/d, H/2 - f y/d), f in pixels.
  const double f_px = 0.5 * camera.height / std::tan(15 * std::numbers::pi / 180);
  const double px = 0.5 * camera.width + f_px * center.x() / camera.distance_m;
  const double py = 0.5 * camera.height - f_px * center.y() / camera.distance_m;
  const SurfaceHit& h = hits[int(py) * camera.width + int(px)];
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(h.object, 0);
  EXPECT_EQ(h.pixel_x, int(px));
  EXPECT_EQ(h.pixel_y, int(py));
  // Facing the camera: the normal points back toward the pinhole.
  EXPECT_GT(h.normal.dot(h.wo), 0.99);
  EXPECT_NEAR((h.position - center).norm(), 0.15, 1e-9);
  // Projected radius ~ f r / d = 6.7 px: 10 px away misses, 4 px away hits.
  EXPECT_FALSE(hits[int(py) * camera.width + int(px) + 10].hit);
  EXPECT_TRUE(hits[int(py) * camera.width + int(px) + 4].hit);
  EXPECT_FALSE(hits[int(py - 10) * camera.width + int(px)].hit);
  // The mirror image position is empty.
  EXPECT_FALSE(hits[int(camera.height - py) * camera.width + int(camera.width - px)].hit);
}

TEST(TraceCamera, CheckerVariesAlbedoOverThePlane) {
  Scene scene;
  const int m = add_lambert(scene, Eigen::Vector3d::Constant(0.8));
  scene.materials[m].checker_albedo = Eigen::Vector3d::Constant(0.1);
  scene.materials[m].checker_cells = 2;
  scene.planes.push_back({{0, 0, 0}, {0, 0, 1}, 1.0, 1.0, m});
  const CameraSpec camera = ortho_camera(32, 2.0);
  const auto hits = trace_camera(scene, camera);
  // Top-left quadrant is cell (0, 0): base albedo; top-right is the checker albedo.
  EXPECT_DOUBLE_EQ(hits[5 * 32 + 5].material.albedo.x(), 0.8);
  EXPECT_DOUBLE_EQ(hits[5 * 32 + 26].material.albedo.x(), 0.1);
  EXPECT_DOUBLE_EQ(hits[26 * 32 + 26].material.albedo.x(), 0.8);
}

TEST(Shadows, SphereCastsShadowOnPlane) {
  Scene scene;
  const int m = add_lambert(scene, Eigen::Vector3d::Constant(0.5));
  scene.spheres.push_back({{0, 0, 0}, 0.3, m});
  scene.planes.push_back({{0, 0, -0.5}, {0, 0, 1}, 2, 2, m});
  const CameraSpec camera = ortho_camera(96);
  const auto hits = trace_camera(scene, camera);
  const Eigen::Vector3d light = Eigen::Vector3d(0.8, 0, 0.6);  // Unit.
  const Image image = render_one_light(scene, hits, light);
  // The shadow's centre on the plane: x = -0.5 * 0.8 / 0.6.
  auto pixel_at = [&](double wx, double wy) {
    return Eigen::Vector2i(int((wx / 1.2 + 1) * 48), int((1 - wy / 1.2) * 48));
  };
  const Eigen::Vector2i shadowed = pixel_at(-0.667, 0.0), lit = pixel_at(0.667, 0.0);
  EXPECT_EQ(hits[shadowed.y() * 96 + shadowed.x()].object, 1);
  EXPECT_FLOAT_EQ(image.at(shadowed.x(), shadowed.y(), 0), 0.0f);
  EXPECT_NEAR(image.at(lit.x(), lit.y(), 0), 0.5 / std::numbers::pi * 0.6, 1e-6);
  EXPECT_FALSE(visible(scene, hits[shadowed.y() * 96 + shadowed.x()].position, light));
  EXPECT_TRUE(visible(scene, hits[lit.y() * 96 + lit.x()].position, light));
}

// A flat height field with one tall narrow bump at its centre.
Scene bump_scene(double bump_height) {
  Scene scene;
  HeightField hf;
  hf.center = {0, 0, 0};
  hf.half_width = hf.half_height = 1.0;
  hf.resolution = 129;
  hf.material = add_lambert(scene, Eigen::Vector3d::Constant(0.5));
  hf.heights.resize(129 * 129);
  for (int i = 0; i < 129; ++i) {
    for (int j = 0; j < 129; ++j) {
      const double x = -1 + 2.0 * j / 128, y = 1 - 2.0 * i / 128;
      hf.heights[i * 129 + j] = float(bump_height * std::exp(-0.5 * (x * x + y * y) / (0.1 * 0.1)));
    }
  }
  scene.height_fields.push_back(hf);
  return scene;
}

TEST(Shadows, HeightFieldBumpShadowsItsLowSideOnlyForGrazingLight) {
  const Scene scene = bump_scene(0.4);
  const CameraSpec camera = ortho_camera(128, 2.0);
  const auto hits = trace_camera(scene, camera);
  // Light from +X at 15 deg above the field's plane; the low side is -X.
  const Eigen::Vector3d grazing(std::cos(15 * std::numbers::pi / 180), 0,
                                std::sin(15 * std::numbers::pi / 180));
  const Eigen::Vector3d overhead(0, 0, 1);
  const Image g = render_one_light(scene, hits, grazing);
  const Image o = render_one_light(scene, hits, overhead);
  // World x = -0.5, y = 0 (pixel 32, 64): flat ground 0.5 m on the shadow side. The bump (0.4 m
  // tall) blocks rays below ~ atan(0.4 / 0.5) = 39 deg there.
  const int y = 64;
  const SurfaceHit& ground = hits[y * 128 + 32];
  ASSERT_TRUE(ground.hit);
  EXPECT_NEAR(ground.position.z(), 0.0, 1e-4);
  EXPECT_GT(ground.normal.dot(grazing), 0.2);  // Faces the light: a shadow, not the back side.
  EXPECT_FLOAT_EQ(g.at(32, y, 0), 0.0f);
  EXPECT_NEAR(o.at(32, y, 0), 0.5 / std::numbers::pi * ground.normal.z(), 1e-5);
  // The same distance on the lit side (+X) is lit by the grazing light.
  const SurfaceHit& lit_side = hits[y * 128 + 96];
  EXPECT_NEAR(g.at(96, y, 0), 0.5 / std::numbers::pi * lit_side.normal.dot(grazing), 1e-5);
  EXPECT_GT(g.at(96, y, 0), 0.03f);
  // The bump's own peak is lit by both.
  EXPECT_GT(g.at(64, y, 0), 0.0f);
  EXPECT_GT(o.at(64, y, 0), 0.1f);
  // Out of the shadow's reach sideways (y = 0.6) the grazing light reaches the ground.
  EXPECT_GT(g.at(32, 25, 0), 0.03f);
  // The hit on the bump lies on the surface: bilinear height at the peak is 0.4 m.
  EXPECT_NEAR(hits[64 * 128 + 64].position.z(), 0.4, 0.01);
}

TEST(Shadows, HeightFieldShadowsOtherObjects) {
  Scene scene = bump_scene(0.4);
  // A small sphere low beside the bump on its far side from the light.
  scene.spheres.push_back({{-0.35, 0, 0.06}, 0.05, 0});
  const Eigen::Vector3d grazing(std::cos(10 * std::numbers::pi / 180), 0,
                                std::sin(10 * std::numbers::pi / 180));
  const Eigen::Vector3d beside_sphere(-0.29, 0, 0.06);
  EXPECT_FALSE(visible(scene, beside_sphere, grazing));
  EXPECT_TRUE(visible(scene, beside_sphere, Eigen::Vector3d(0, 0, 1)));
  // A point above the field's maximum sees a grazing light (the march exits early).
  EXPECT_TRUE(visible(scene, Eigen::Vector3d(-0.5, 0, 0.5), grazing));
}

// ---------------------------------------------------------------------------------------------
// The simulated sensor.

struct UniformRig {
  Stage stage;
  double radiance = 0;  // Of the lit patch, per channel.
};

// One LED along +Z lighting a Lambertian plane that fills a 64x64 orthographic view.
UniformRig uniform_rig(double albedo = 0.5) {
  UniformRig rig;
  rig.stage = stage_with_directions({Eigen::Vector3d(0, 0, 1)});
  rig.stage.camera = ortho_camera(64, 1.0);
  rig.stage.camera.radiometric_scale = 1.0;
  rig.stage.camera.bit_depth = 12;
  rig.radiance = albedo / std::numbers::pi * rig.stage.leds[0].intensity;
  return rig;
}

Scene plane_scene(double albedo = 0.5) {
  Scene scene;
  scene.planes.push_back(
      {{0, 0, 0}, {0, 0, 1}, 2, 2, add_lambert(scene, Eigen::Vector3d::Constant(albedo))});
  return scene;
}

struct Stats {
  double mean = 0, variance = 0;
  int min = 1 << 30, max = -1;
};
Stats stats(const RawFrame& f) {
  Stats s;
  double sum = 0, sum2 = 0;
  for (uint16_t v : f.pixels) {
    sum += v;
    sum2 += double(v) * v;
    s.min = std::min<int>(s.min, v);
    s.max = std::max<int>(s.max, v);
  }
  const double n = double(f.pixels.size());
  s.mean = sum / n;
  s.variance = sum2 / n - s.mean * s.mean;
  return s;
}

TEST(SimSensor, MeanAndVarianceFollowTheSensorModel) {
  const UniformRig rig = uniform_rig();
  SimStage sim(rig.stage, plane_scene(), /*seed=*/7);
  sim.lights().set_light(0, true);
  const SimulatedSensor& s = rig.stage.camera.simulated;
  // An exposure for 5000 signal electrons.
  const FrameRequest request{5000.0 / (rig.radiance * s.full_well_e), 1.0, 1};
  const CapturedFrame frame = sim.camera().capture(request);
  EXPECT_EQ(frame.exposure_s, request.exposure_s);
  EXPECT_EQ(frame.gain, 1.0);
  ASSERT_EQ(frame.raw.pixels.size(), 64u * 64u * 3u);
  const double max_dn = 4095;
  const double mean_e = rig.radiance * request.exposure_s * s.full_well_e +
                        s.dark_current_e_per_s * request.exposure_s;
  const double expected_mean = (mean_e / s.full_well_e + s.black_level) * max_dn;
  const double dn_per_e = max_dn / s.full_well_e;
  const double expected_var = (mean_e + s.read_noise_e * s.read_noise_e) * dn_per_e * dn_per_e +
                              1.0 / 12.0;  // Quantisation.
  const Stats st = stats(frame.raw);
  EXPECT_NEAR(st.mean, expected_mean, 4 * std::sqrt(expected_var / 12288) + 0.05);
  EXPECT_NEAR(st.variance, expected_var, 0.1 * expected_var);
}

TEST(SimSensor, LowLightUsesPoissonAndGainScales) {
  const UniformRig rig = uniform_rig();
  SimStage sim(rig.stage, plane_scene(), 3);
  sim.lights().set_light(0, true);
  const SimulatedSensor& s = rig.stage.camera.simulated;
  // 20 signal electrons (Poisson regime), gain 16 to lift it well above quantisation.
  FrameRequest request{20.0 / (rig.radiance * s.full_well_e), 16.0, 2};
  const Stats st = stats(sim.camera().capture(request).raw);
  const double mean_e = 20.0 + s.dark_current_e_per_s * request.exposure_s;
  const double dn_per_e = 16.0 * 4095 / s.full_well_e;
  // Sigma of the mean over 12288 samples: sqrt(36 e^2 * 3.28^2 / 12288) = 0.18 DN.
  EXPECT_NEAR(st.mean, (mean_e * 16.0 / s.full_well_e + s.black_level) * 4095, 0.8);
  const double expected_var = (mean_e + s.read_noise_e * s.read_noise_e) * dn_per_e * dn_per_e;
  EXPECT_NEAR(st.variance, expected_var, 0.1 * expected_var);
}

TEST(SimSensor, SaturatesAtFullScale) {
  const UniformRig rig = uniform_rig();
  SimStage sim(rig.stage, plane_scene(), 1);
  sim.lights().set_light(0, true);
  const Stats st = stats(sim.camera().capture({10.0, 1.0, 3}).raw);
  EXPECT_EQ(st.min, 4095);
  EXPECT_EQ(st.max, 4095);
}

// The two levels of the sensor model agree: the camera's frame noise, in radiance units, is what
// field_noise_of says a field carries (dark current adds < 0.2% here).
TEST(SimSensor, FieldNoiseIsTheCameraNoiseInRadianceUnits) {
  const UniformRig rig = uniform_rig();
  SimStage sim(rig.stage, plane_scene(), /*seed=*/11);
  sim.lights().set_light(0, true);
  const SimulatedSensor& s = rig.stage.camera.simulated;
  const double exposure_s = 5000.0 / (rig.radiance * s.full_well_e);
  const Stats st = stats(sim.camera().capture({exposure_s, 1.0, 4}).raw);
  const double max_dn = 4095;
  const double radiance_per_dn = rig.stage.camera.radiometric_scale / exposure_s / max_dn;
  const double variance = (st.variance - 1.0 / 12.0) * radiance_per_dn * radiance_per_dn;
  const capture::FieldNoise noise = field_noise_of(rig.stage.camera, exposure_s);
  const double expected = noise.read_variance + noise.shot_variance_per_unit * rig.radiance;
  EXPECT_NEAR(variance, expected, 0.1 * expected);
}

// The field-level model: residuals against the ideal field have the FieldNoise's variance, the
// noise is recorded as measured, and dead LEDs stay invalid and zero.
TEST(NoisyField, ResidualsHaveTheFieldNoiseVariance) {
  UniformRig rig = uniform_rig();
  rig.stage = stage_with_directions({Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.6, 0, 0.8)});
  rig.stage.camera = ortho_camera(64, 1.0);
  capture::FieldNoise noise;
  noise.read_variance = 1e-5;
  noise.shot_variance_per_unit = 2e-4;
  SimFieldOptions options;
  options.dead_leds = {1};
  const capture::ReflectanceField ideal = render_ideal_field(rig.stage, plane_scene(), options);
  const capture::ReflectanceField noisy =
      render_noisy_field(rig.stage, plane_scene(), noise, /*seed=*/5, options);
  EXPECT_FALSE(ideal.noise.measured);
  EXPECT_TRUE(noisy.noise.measured);
  EXPECT_EQ(noisy.noise.read_variance, noise.read_variance);
  EXPECT_FALSE(noisy.lights()[1].valid);
  double sum = 0, sum2 = 0, expected = 0;
  const double n = 64.0 * 64.0 * 3.0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double d = double(noisy.at(x, y, 0, c)) - ideal.at(x, y, 0, c);
        sum += d;
        sum2 += d * d;
        expected += noise.read_variance + noise.shot_variance_per_unit * ideal.at(x, y, 0, c);
        EXPECT_EQ(noisy.at(x, y, 1, c), 0.0f);
      }
    }
  }
  expected /= n;
  EXPECT_NEAR(sum / n, 0.0, 4 * std::sqrt(expected / n));
  EXPECT_NEAR(sum2 / n, expected, 0.05 * expected);  // Sampling error ~1.3%.
}

TEST(SimSensor, DarkFrameIsBlackLevelPlusDarkCurrent) {
  const UniformRig rig = uniform_rig();
  SimStage sim(rig.stage, plane_scene(), 1);
  const SimulatedSensor& s = rig.stage.camera.simulated;
  sim.lights().set_light(0, true);
  sim.lights().all_off();
  const double exposure_s = 20.0;  // 100 dark electrons.
  const Stats st = stats(sim.camera().capture({exposure_s, 1.0, 4}).raw);
  const double mean_e = s.dark_current_e_per_s * exposure_s;
  EXPECT_NEAR(st.mean, (mean_e / s.full_well_e + s.black_level) * 4095, 0.1);
  // A dead LED emits nothing: the lit frame equals a dark one.
  sim.set_dead_led(0, true);
  sim.lights().set_light(0, true);
  const Stats dead = stats(sim.camera().capture({exposure_s, 1.0, 4}).raw);
  EXPECT_NEAR(dead.mean, st.mean, 1e-9);
}

TEST(SimSensor, SameKeyIsBitIdenticalDifferentKeyIsNot) {
  const UniformRig rig = uniform_rig();
  SimStage a(rig.stage, plane_scene(), 42);
  SimStage b(rig.stage, plane_scene(), 42);
  a.lights().set_light(0, true);
  b.lights().set_light(0, true);
  const FrameRequest request{0.02, 1.0, 1234};
  const RawFrame first = a.camera().capture(request).raw;
  a.camera().capture({0.02, 1.0, 99});  // Something else in between.
  EXPECT_EQ(a.camera().capture(request).raw.pixels, first.pixels);
  EXPECT_EQ(b.camera().capture(request).raw.pixels, first.pixels);  // A fresh stage too.
  EXPECT_NE(a.camera().capture({0.02, 1.0, 1235}).raw.pixels, first.pixels);
  SimStage other_seed(rig.stage, plane_scene(), 43);
  other_seed.lights().set_light(0, true);
  EXPECT_NE(other_seed.camera().capture(request).raw.pixels, first.pixels);
}

TEST(SimSensor, GammaResponse) {
  UniformRig rig = uniform_rig();
  rig.stage.camera.response.kind = CameraResponse::Kind::kGamma;
  rig.stage.camera.response.gamma = 2.2;
  rig.stage.camera.simulated.read_noise_e = 0;
  rig.stage.camera.simulated.black_level = 0;
  SimStage sim(rig.stage, plane_scene(), 5);
  sim.lights().set_light(0, true);
  const SimulatedSensor& s = rig.stage.camera.simulated;
  const double x = 0.25;  // Normalised exposure.
  const double exposure_s = x / rig.radiance;
  const Stats st = stats(sim.camera().capture({exposure_s, 1.0, 6}).raw);
  const double dark_x = s.dark_current_e_per_s * exposure_s / s.full_well_e;
  // Shot noise (sigma_x = 0.0035) bends the mean of a concave curve by under 0.1 DN.
  EXPECT_NEAR(st.mean, std::pow(x + dark_x, 1 / 2.2) * 4095, 0.5);
}

TEST(SimStage, FrameSumsLitLedsTimesTheirIrradiance) {
  Stage stage = stage_with_directions({Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0.6, 0.8)});
  stage.camera = ortho_camera(32, 1.0);
  stage.camera.radiometric_scale = 1.0;
  stage.camera.simulated.read_noise_e = 0;
  stage.leds[0].intensity = 0.5;
  stage.leds[1].color_gain = {1.0, 0.5, 0.25};
  SimStage sim(stage, plane_scene(0.5), 9);
  EXPECT_EQ(sim.lights().num_lights(), 2);
  EXPECT_EQ(sim.hits().size(), 32u * 32u);
  EXPECT_THROW(sim.lights().set_light(2, true), HardwareError);
  sim.lights().set_light(0, true);
  sim.lights().set_light(1, true);
  const double exposure_s = 0.5;
  const RawFrame f = sim.camera().capture({exposure_s, 1.0, 8}).raw;
  const SimulatedSensor& s = stage.camera.simulated;
  for (int c = 0; c < 3; ++c) {
    const double radiance =
        0.5 / std::numbers::pi * (0.5 * 1.0 + stage.leds[1].color_gain[c] * 0.8);
    const double x =
        radiance * exposure_s + s.dark_current_e_per_s * exposure_s / s.full_well_e + s.black_level;
    double mean = 0;
    for (int p = 0; p < 32 * 32; ++p) mean += f.pixels[p * 3 + c];
    mean /= 32 * 32;
    EXPECT_NEAR(mean, x * 4095, 1.0) << "channel " << c;
  }
  // The cached ideal image is R(x, l) for LED 1: albedo/pi * cos.
  EXPECT_NEAR(sim.one_light_image(1).at(5, 5, 0), 0.5 / std::numbers::pi * 0.8, 1e-6);
  const CameraInfo info = sim.camera().info();
  EXPECT_EQ(info.width, 32);
  EXPECT_EQ(info.bit_depth, 12);
  EXPECT_EQ(info.channels, 3);
}

// One-light images kept within a budget (30 GB at 4096^2 otherwise) give the same frames.
TEST(SimStage, OneLightCacheStaysWithinItsBudgetWithTheSameFrames) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(12, 10.0));
  stage.camera = ortho_camera(24, 1.0);
  SimStage unbounded(stage, plane_scene(0.5), 3), bounded(stage, plane_scene(0.5), 3);
  bounded.set_one_light_cache_bytes(2 * 24 * 24 * 3 * sizeof(float));  // Two images.
  for (int led = 0; led < 12; ++led) {
    for (SimStage* sim : {&unbounded, &bounded}) {
      sim->lights().all_off();
      sim->lights().set_light(led, true);
      if (led % 4 == 3) sim->lights().set_light(0, true);  // And an earlier one too.
    }
    const FrameRequest request{0.01, 1.0, uint64_t(led)};
    EXPECT_EQ(unbounded.camera().capture(request).raw.pixels,
              bounded.camera().capture(request).raw.pixels);
    EXPECT_LE(bounded.cached_one_light_images(), 2) << "LED " << led;
  }
}

TEST(SimStage, InjectedTimeouts) {
  const UniformRig rig = uniform_rig();
  SimStage sim(rig.stage, plane_scene(), 1);
  sim.inject_timeouts({5, 6});
  EXPECT_NO_THROW(sim.camera().capture({0.01, 1.0, 4}));
  EXPECT_THROW(sim.camera().capture({0.01, 1.0, 5}), CameraTimeout);
  EXPECT_NO_THROW(sim.camera().capture({0.01, 1.0, 5}));  // Once per key.
  EXPECT_THROW(sim.camera().capture({0.01, 1.0, 6}), CameraTimeout);
  sim.inject_timeout_after(2);
  EXPECT_NO_THROW(sim.camera().capture({0.01, 1.0, 7}));
  EXPECT_NO_THROW(sim.camera().capture({0.01, 1.0, 8}));
  EXPECT_THROW(sim.camera().capture({0.01, 1.0, 9}), CameraTimeout);
  EXPECT_THROW(sim.camera().capture({0.01, 1.0, 9}), CameraTimeout);  // Until cleared.
  sim.inject_timeout_after(-1);
  EXPECT_NO_THROW(sim.camera().capture({0.01, 1.0, 9}));
}

TEST(SimStage, DefaultSceneTimings) {
  const Stage stage = default_stage();
  const Scene scene = default_scene();
  using Clock = std::chrono::steady_clock;
  auto seconds = [](Clock::time_point a) {
    return std::chrono::duration<double>(Clock::now() - a).count();
  };
  auto t0 = Clock::now();
  const auto hits = trace_camera(scene, stage.camera);
  const double trace_s = seconds(t0);
  int hit_count = 0;
  for (const auto& h : hits) hit_count += h.hit;
  EXPECT_EQ(hit_count, stage.camera.width * stage.camera.height);  // The backdrop fills the view.

  SimStage sim(stage, scene, 1);
  t0 = Clock::now();
  double total = 0;
  for (int l = 0; l < int(stage.leds.size()); ++l) {
    const Image& img = sim.one_light_image(l);
    for (float v : img.pixels) {
      ASSERT_TRUE(std::isfinite(v));
      total += v;
    }
  }
  const double all_lights_s = seconds(t0);
  EXPECT_GT(total, 0);
  const int frames = 50;
  t0 = Clock::now();
  for (int i = 0; i < frames; ++i) {
    sim.lights().all_off();
    sim.lights().set_light(i % int(stage.leds.size()), true);
    sim.camera().capture({0.01, 1.0, uint64_t(i)});
  }
  const double frame_ms = seconds(t0) / frames * 1e3;
  std::cout << "[timing] default scene " << stage.camera.width << "x" << stage.camera.height
            << ": trace_camera " << trace_s * 1e3 << " ms; all " << stage.leds.size()
            << " one-light images " << all_lights_s << " s; one cached frame " << frame_ms
            << " ms\n";
}

// A Lambertian plane at z = 0 under one LED at P = d0 * dir (near field): the radiance is
// albedo / pi * E0 * cos(theta) * (d0 / r)^2, r = |P - x|, cos(theta) = n . (P - x) / r.
TEST(SimStage, NearLedLightsALambertPlaneAsCosOverRSquared) {
  const double albedo = 0.5, d0 = 1.2;
  Stage stage = stage_with_directions({Eigen::Vector3d(0.3, 0.5, 0.8).normalized()});
  stage.leds[0].distance_m = d0;
  stage.leds[0].intensity = 0.7;
  stage.camera = ortho_camera(64, 2.0);
  Scene scene = plane_scene(albedo);  // 4 m x 4 m: fills the view.
  const Eigen::Vector3d led_pos = d0 * stage.leds[0].dir_in_stage;
  // Beyond the LED on the line from the origin (out of view, y > 1.1 m): a shadow ray that ran
  // past the LED would darken the origin.
  scene.spheres.push_back({2.0 * led_pos, 0.1, 0});
  SimStage sim(stage, scene, 3);
  const Image& image = sim.one_light_image(0);
  double worst_rel = 0, min_r = 1e9, max_r = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      const Eigen::Vector2d xy = ortho_pixel_xy(stage.camera, x, y);
      const Eigen::Vector3d to_led = led_pos - Eigen::Vector3d(xy.x(), xy.y(), 0);
      const double r = to_led.norm();
      const double expected = albedo / std::numbers::pi * (to_led.z() / r) * (d0 * d0) / (r * r);
      min_r = std::min(min_r, r);
      max_r = std::max(max_r, r);
      for (int c = 0; c < 3; ++c) {
        worst_rel = std::max(worst_rel, std::abs(image.at(x, y, c) / expected - 1.0));
      }
    }
  }
  std::cout << "near LED at " << d0 << " m over a plane (r from " << min_r << " to " << max_r
            << " m): worst relative error " << worst_rel << "\n";
  // Measured: 5.9e-8 (float rounding); r spans 0.97 to 2.30 m, so (d0/r)^2 spans 0.27 to 1.53.
  EXPECT_LT(worst_rel, 1e-5);
  // A captured frame scales it by the LED's irradiance at the origin, as for distant LEDs.
  sim.lights().set_light(0, true);
  const double exposure_s = 0.05;
  const RawFrame f = sim.camera().capture({exposure_s, 1.0, 1}).raw;
  const SimulatedSensor& s = stage.camera.simulated;
  const int px = 40, py = 20;
  const double expected_x = 0.7 * image.at(px, py, 0) * exposure_s +
                            s.dark_current_e_per_s * exposure_s / s.full_well_e + s.black_level;
  // Shot noise at about 0.3 of full scale: sigma 3.5 DN; 5 sigma.
  EXPECT_NEAR(f.pixels[(py * 64 + px) * 3], expected_x * 4095, 18.0);
}

TEST(SimStage, NearLedShadowsOnlyWhatLiesBetweenItAndTheSurface) {
  const double d0 = 1.0;
  Stage stage = stage_with_directions({Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, 1)});
  stage.leds[1].distance_m = d0;  // LED 0 distant, LED 1 near, same direction.
  stage.camera = ortho_camera(64, 2.0);
  Scene scene = plane_scene(0.5);
  // A ball halfway to the LED: its shadow on the plane is a disc of radius 0.1 * (1 / 0.5) from
  // the near LED (a cone), of radius 0.1 from the distant one (a cylinder).
  scene.spheres.push_back({{0, 0, 0.5}, 0.1, 0});
  SimStage sim(stage, scene, 3);
  const Image& distant = sim.one_light_image(0);
  const Image& near = sim.one_light_image(1);
  int checked = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      const SurfaceHit& h = sim.hits()[y * 64 + x];
      if (h.object != 1) continue;  // The ball hides the plane here.
      const double rho = ortho_pixel_xy(stage.camera, x, y).norm();
      // The cone's edge: sin(half angle) = 0.1 / 0.5 at the LED, so radius on the plane
      // d0 * tan(asin(0.2)) = 0.204 m. Skip the pixels the edge crosses.
      const double cone = d0 * std::tan(std::asin(0.2));
      if (std::abs(rho - cone) < 0.04 || std::abs(rho - 0.1) < 0.04) continue;
      ++checked;
      EXPECT_EQ(near.at(x, y, 0) == 0.0f, rho < cone) << x << "," << y;
      EXPECT_EQ(distant.at(x, y, 0) == 0.0f, rho < 0.1) << x << "," << y;
    }
  }
  EXPECT_GT(checked, 3000);
  // Distant LEDs are untouched: bit for bit what render_one_light gives.
  const Image reference = render_one_light(sim.scene(), sim.hits(), stage.leds[0].dir_in_stage);
  EXPECT_EQ(distant.pixels, reference.pixels);
  EXPECT_EQ(render_one_led(sim.scene(), sim.hits(), stage.leds[0]).pixels, reference.pixels);
  EXPECT_EQ(render_one_led(sim.scene(), sim.hits(), stage.leds[1]).pixels, near.pixels);
}

TEST(SimStage, NearLedWithoutAPositiveDistanceIsRefused) {
  Stage stage = stage_with_directions({Eigen::Vector3d(0, 0, 1)});
  stage.leds[0].distance_m = 0.0;
  stage.camera = ortho_camera(8);
  EXPECT_THROW(SimStage(stage, plane_scene(), 1), InputError);
}

}  // namespace
}  // namespace ls::sim
