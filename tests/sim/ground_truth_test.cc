#include "sim/ground_truth.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <numbers>

#include "lightstage/errors.h"
#include "sim/envmaps.h"
#include "sim/sim_stage.h"
#include "tests/support/test_support.h"

namespace ls::sim {
namespace {

Scene lone_sphere(const physics::brdf::Material& material, double radius = 0.5) {
  Scene scene;
  SceneMaterial m;
  m.name = "m";
  m.base = material;
  scene.materials.push_back(m);
  scene.spheres.push_back({{0, 0, 0}, radius, 0});
  return scene;
}

CameraSpec square_ortho_camera(int size, double view_height_m) {
  CameraSpec camera;
  camera.width = camera.height = size;
  camera.ortho_height_m = view_height_m;
  return camera;
}

Eigen::Vector3d rotate_y(const Eigen::Vector3d& d, double deg) {
  const double a = deg * std::numbers::pi / 180, c = std::cos(a), s = std::sin(a);
  return {c * d.x() + s * d.z(), d.y(), -s * d.x() + c * d.z()};
}

TEST(GroundTruth, LambertSphereUnderConstantEnvironmentIsAlbedoTimesRadiance) {
  physics::brdf::Material mat;
  mat.albedo = {0.7, 0.5, 0.3};
  const Scene scene = lone_sphere(mat);
  const Eigen::Vector3d c(0.5, 1.0, 2.0);
  Image constant(64, 32, 3);
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 64; ++x) {
      for (int k = 0; k < 3; ++k) constant.at(x, y, k) = float(c[k]);
    }
  }
  const physics::EnvironmentMap map(constant);
  const CameraSpec camera = square_ortho_camera(40, 1.2);
  GroundTruthOptions options;
  options.directions_width = 256;
  const Image truth = render_ground_truth(scene, camera, map, options);
  const auto hits = trace_camera(scene, camera);
  int checked = 0;
  double worst = 0;
  for (int y = 0; y < 40; ++y) {
    for (int x = 0; x < 40; ++x) {
      for (int k = 0; k < 3; ++k) {
        if (!hits[y * 40 + x].hit) {
          EXPECT_EQ(truth.at(x, y, k), 0.0f);
          continue;
        }
        const double expected = mat.albedo[k] * c[k];
        worst = std::max(worst, std::abs(truth.at(x, y, k) / expected - 1));
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 3 * 800);
  EXPECT_LT(worst, 0.005) << "irradiance pi*c, radiance albedo*c";
}

struct Agreement {
  int agree = 0;     // Both lit, within tolerance in every channel.
  int disagree = 0;  // Both lit, beyond tolerance.
  int penumbra = 0;  // Lit in one, shadowed in the other: a shadow edge blurred by the source.
};

// Under the small source, the truth is the one-light image toward the source times its irradiance.
Agreement compare_with_one_light(const Scene& scene, const CameraSpec& camera, double rotation_deg,
                                 double tolerance) {
  const physics::EnvironmentMap map(make_small_source(512));
  const Eigen::Vector3d irradiance = map.integral();
  const Eigen::Vector3d dir = rotate_y(small_source_direction(), rotation_deg);
  GroundTruthOptions options;
  options.directions_width = 256;
  options.rotation_deg = rotation_deg;
  const Image truth = render_ground_truth(scene, camera, map, options);
  const auto hits = trace_camera(scene, camera);
  const Image one = render_one_light(scene, hits, dir);
  Agreement a;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const SurfaceHit& h = hits[y * camera.width + x];
      if (!h.hit || h.normal.dot(dir) < 0.3) continue;  // Away from the terminator.
      const bool lit_truth = truth.at(x, y, 0) > 0, lit_one = one.at(x, y, 0) > 0;
      if (lit_truth != lit_one) {
        ++a.penumbra;
        continue;
      }
      if (!lit_one) continue;
      bool ok = true;
      for (int k = 0; k < 3; ++k) {
        const double expected = one.at(x, y, k) * irradiance[k];
        ok &= std::abs(truth.at(x, y, k) - expected) <= tolerance * expected;
      }
      (ok ? a.agree : a.disagree)++;
    }
  }
  return a;
}

void expect_matches_one_light(const Scene& scene, const CameraSpec& camera, double rotation_deg,
                              double tolerance) {
  const Agreement a = compare_with_one_light(scene, camera, rotation_deg, tolerance);
  EXPECT_GT(a.agree, 80);
  EXPECT_EQ(a.disagree, 0);
  EXPECT_LT(a.penumbra, 10);
}

TEST(GroundTruth, SmallSourceMatchesOneLightImage) {
  physics::brdf::Material mat;
  mat.diffuse = physics::brdf::DiffuseModel::kOrenNayar;
  mat.sigma_rad = 0.35;
  mat.albedo = {0.6, 0.5, 0.4};
  expect_matches_one_light(lone_sphere(mat), square_ortho_camera(48, 1.2), 0.0, 0.01);
}

// A sphere above a plane under a 2-degree disc at 45 degrees: the plane sees none of it in the
// middle of the sphere's shadow, all of it far away, and about half on the shadow's edge.
TEST(GroundTruth, SourceVisibilityIsTheShareOfTheDiscSeen) {
  Scene scene;
  SceneMaterial m;
  m.name = "m";
  scene.materials.push_back(m);
  scene.spheres.push_back({{0, 0, 1}, 0.3, 0});
  scene.planes.push_back({{0, 0, 0}, {0, 0, 1}, 2.0, 2.0, 0});
  const CameraSpec camera = square_ortho_camera(96, 3.0);
  const Eigen::Vector3d dir = Eigen::Vector3d(1, 0, 1).normalized();
  const Image visibility =
      render_source_visibility(scene, camera, dir, 2.0 * std::numbers::pi / 180);
  ASSERT_EQ(visibility.channels, 1);
  // The pixel whose surface point is nearest `at` (on the plane: the camera looks down -z).
  const auto hits = trace_camera(scene, camera);
  const auto seen_at = [&](const Eigen::Vector3d& at) {
    const SurfaceHit* best = &hits.front();
    for (const SurfaceHit& h : hits) {
      if ((h.position - at).norm() < (best->position - at).norm()) best = &h;
    }
    return visibility.at(best->pixel_x, best->pixel_y, 0);
  };
  // The shadow of the sphere's centre falls at (-1, 0, 0); its edge across the light at y = +-0.3.
  EXPECT_EQ(seen_at({-1, 0, 0}), 0.0f);
  EXPECT_EQ(seen_at({1, 0, 0}), 1.0f);
  EXPECT_NEAR(seen_at({-1, 0.3, 0}), 0.5, 0.3);
  EXPECT_NEAR(seen_at({-1, -0.3, 0}), 0.5, 0.3);
  EXPECT_THROW(render_source_visibility(scene, camera, dir, -1.0), InputError);
}

TEST(GroundTruth, RotationTurnsTheMapAboutY) {
  physics::brdf::Material mat;
  mat.albedo = {0.6, 0.6, 0.6};
  expect_matches_one_light(lone_sphere(mat), square_ortho_camera(48, 1.2), 90.0, 0.01);
  expect_matches_one_light(lone_sphere(mat), square_ortho_camera(48, 1.2), -40.0, 0.01);
}

TEST(GroundTruth, DefaultSceneWithShadowsMatchesOneLightUnderSmallSource) {
  // The source stands 19 deg above the relief's plane: bumps and ridges cast long shadows whose
  // edges the 4 deg disc blurs. Inside and outside them, truth and one-light image agree.
  const Agreement a =
      compare_with_one_light(default_scene(), square_ortho_camera(96, 2.4), 0.0, 0.02);
  EXPECT_GT(a.agree, 4000);
  EXPECT_LT(a.disagree, a.agree / 10) << "penumbra pixels lit in both: " << a.disagree;
  EXPECT_LT(a.penumbra, a.agree / 10);
}

TEST(GroundTruth, BlockVisibilityApproximatesExact) {
  const Scene scene = default_scene();
  const physics::EnvironmentMap map(make_studio(256));
  GroundTruthOptions options;
  options.directions_width = 128;
  const CameraSpec camera = square_ortho_camera(48, 2.4);
  const Image exact = render_ground_truth(scene, camera, map, options);
  options.visibility_block = 4;
  const Image blocks = render_ground_truth(scene, camera, map, options);
  // Area lights: the block shortcut only blurs shadow detail; the image stays within 2% RMS.
  EXPECT_TRUE(ls::testing::ImageNear(blocks, exact, 0.02));
}

TEST(GroundTruth, CoverageRestrictsDirections) {
  physics::brdf::Material mat;
  const Scene scene = lone_sphere(mat);
  const physics::EnvironmentMap map(make_small_source(256));
  const CameraSpec camera = square_ortho_camera(24, 1.2);
  GroundTruthOptions all;
  all.directions_width = 128;
  const Image full = render_ground_truth(scene, camera, map, all);
  GroundTruthOptions covered = all;
  covered.covered_by_leds = {small_source_direction(), Eigen::Vector3d(0, 1, 0)};
  covered.coverage_radius_rad = 10 * std::numbers::pi / 180;
  EXPECT_TRUE(ls::testing::ImageNear(render_ground_truth(scene, camera, map, covered), full, 1e-6));
  covered.covered_by_leds = {-small_source_direction()};
  const Image none = render_ground_truth(scene, camera, map, covered);
  EXPECT_EQ(*std::max_element(none.pixels.begin(), none.pixels.end()), 0.0f);
  EXPECT_GT(*std::max_element(full.pixels.begin(), full.pixels.end()), 0.05f);
}

TEST(Envmaps, ShapesAndPower) {
  for (const Image& img : {make_sky_with_sun(256), make_studio(256), make_small_source(256)}) {
    EXPECT_EQ(img.width, 256);
    EXPECT_EQ(img.height, 128);
    EXPECT_EQ(img.channels, 3);
    for (float v : img.pixels) ASSERT_TRUE(std::isfinite(v) && v >= 0);
    EXPECT_NO_THROW(physics::EnvironmentMap{img});
  }
  // The small source gives irradiance 1 at normal incidence: its integral is 2 / (1 + cos r).
  const physics::EnvironmentMap small(make_small_source(512));
  const double r = kSmallSourceRadiusDeg * std::numbers::pi / 180;
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(small.integral()[k], 2 / (1 + std::cos(r)), 0.01);
  // Its light comes from where small_source_direction says.
  const Eigen::Vector2d uv = physics::EnvironmentMap::uv(small_source_direction());
  EXPECT_GT(small.radiance().at(int(uv.x() * 512), int(uv.y() * 256), 0),
            0.5 * small_source_radiance());

  // The sun: a limb-darkened disc of power L0 pi r^2 * 0.8, far brighter than the sky.
  const physics::EnvironmentMap sky(make_sky_with_sun(1024));
  const Eigen::Vector3d sun = sky_sun_direction();
  EXPECT_NEAR(std::asin(sun.y()) * 180 / std::numbers::pi, 35.0, 1e-9);
  const double rs = kSunRadiusDeg * std::numbers::pi / 180;
  double sun_power = 0, sky_power = 0, zenith = sky.radiance().at(0, 0, 2);
  for (int y = 0; y < sky.height(); ++y) {
    for (int x = 0; x < sky.width(); ++x) {
      const double dw = sky.pixel_solid_angle_sr(y);
      const double g = sky.radiance().at(x, y, 1);
      (sky.pixel_direction(x, y).dot(sun) > std::cos(rs + 0.01) ? sun_power : sky_power) += g * dw;
    }
  }
  const double disc = 2500 * 0.93 * std::numbers::pi * rs * rs * 0.8;
  EXPECT_NEAR(sun_power, disc, 0.05 * disc);  // Plus a little sky inside the test cone.
  EXPECT_GT(sun_power, 0.3 * sky_power);
  EXPECT_GT(zenith, sky.radiance().at(0, sky.height() / 2 - 1, 2) * 0.5);  // Blue overhead.
  EXPECT_GT(sky.radiance().at(0, 0, 2), sky.radiance().at(0, 0, 0));
}

TEST(GroundTruth, DefaultSceneTiming) {
  // LIGHTSTAGE_GT_DIRECTIONS=256 times the full-size quadrature (slow on 2 cores);
  // LIGHTSTAGE_GT_BLOCK=4 the approximate block visibility.
  const char* env = std::getenv("LIGHTSTAGE_GT_DIRECTIONS");
  const char* block_env = std::getenv("LIGHTSTAGE_GT_BLOCK");
  const int directions = env ? std::atoi(env) : 64;
  const Stage stage = default_stage();
  const Scene scene = default_scene();
  const physics::EnvironmentMap map(make_studio(512));
  GroundTruthOptions options;
  options.directions_width = directions;
  options.visibility_block = block_env ? std::atoi(block_env) : 1;
  const auto t0 = std::chrono::steady_clock::now();
  const Image truth = render_ground_truth(scene, stage.camera, map, options);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  double sum = 0;
  for (float v : truth.pixels) {
    ASSERT_TRUE(std::isfinite(v));
    sum += v;
  }
  EXPECT_GT(sum, 0);
  std::cout << "[timing] ground truth, default scene " << stage.camera.width << "x"
            << stage.camera.height << ", studio map, " << directions << "x" << directions / 2
            << " directions, visibility_block " << options.visibility_block << ": " << s << " s\n";
}

}  // namespace
}  // namespace ls::sim
