#include "sim/rti_scenes.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace ls::sim {

namespace {}  // namespace

const char* to_string(RtiScene scene) {
  switch (scene) {
    case RtiScene::kMatte:
      return "matte";
    case RtiScene::kGlossy:
      return "glossy";
    case RtiScene::kShadowed:
      return "shadowed";
  }
  return "?";
}

Scene rti_scene(RtiScene which) {
  Scene scene;
  scene.source = std::string("<rti scene ") + to_string(which) + ">";
  SceneMaterial backdrop;
  backdrop.name = "backdrop";
  backdrop.base.albedo = {0.45, 0.45, 0.4};
  SceneMaterial ball;
  ball.name = "ball";
  ball.base.albedo = {0.7, 0.45, 0.3};
  if (which == RtiScene::kGlossy) {
    ball.base.specular = physics::brdf::SpecularModel::kTorranceSparrow;
    ball.base.ks = {0.5, 0.5, 0.5};
    ball.base.roughness = 0.2;
  }
  scene.materials = {backdrop, ball};
  Plane plane;
  plane.center = {0, 0, which == RtiScene::kShadowed ? -0.55 : -1.2};
  plane.normal = {0, 0, 1};
  plane.half_width = plane.half_height = 2.0;
  plane.material = 0;
  scene.planes.push_back(plane);
  Sphere sphere;
  sphere.radius = which == RtiScene::kShadowed ? 0.5 : 0.9;
  sphere.material = 1;
  scene.spheres.push_back(sphere);
  return scene;
}

Stage rti_dome_stage(int count, double min_elevation_deg, int resolution) {
  // fibonacci_dome_directions spreads LEDs over the hemisphere about +Y; rotate +Y onto +Z
  // (x, y, z) -> (x, -z, y), a proper rotation about +X.
  std::vector<Eigen::Vector3d> dirs;
  for (const auto& d : fibonacci_dome_directions(count, min_elevation_deg)) {
    dirs.push_back({d.x(), -d.z(), d.y()});
  }
  Stage stage = stage_with_directions(dirs);
  stage.name = "rti-dome-" + std::to_string(count);
  stage.camera.width = stage.camera.height = resolution;
  return stage;
}

NearRtiDome near_rti_dome(int leds, int width, int height, double radius_m, double fov_y_deg,
                          uint64_t seed) {
  NearRtiDome dome;
  dome.stage = rti_dome_stage(leds, 15.0, width);
  dome.stage.name = "near-rti-dome-" + std::to_string(leds);
  CameraSpec& camera = dome.stage.camera;
  camera.width = width;
  camera.height = height;
  camera.fov_y_deg = fov_y_deg;
  camera.ortho_height_m = 0.36 * radius_m;
  // A pinhole camera as high as sees 0.36 radii of the table.
  if (fov_y_deg > 0)
    camera.distance_m = 0.18 * radius_m / std::tan(0.5 * fov_y_deg * std::numbers::pi / 180);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.003, 0.003);
  for (Led& led : dome.stage.leds) led.distance_m = radius_m * (1.0 + jitter(rng));

  SceneMaterial backdrop;
  backdrop.name = "backdrop";
  backdrop.base.albedo = {0.3, 0.3, 0.3};
  SceneMaterial black;
  black.name = "sphere";
  black.base.albedo = {0, 0, 0};
  dome.scene.materials = {backdrop, black};
  dome.scene.source = "<near-light rti dome>";
  Plane plane;
  plane.half_width = plane.half_height = 2.0 * radius_m;
  dome.scene.planes.push_back(plane);
  const double ball_radius = 0.04 * radius_m;
  const double half_width = 0.5 * camera.ortho_height_m * width / height;
  for (const double side : {-1.0, 1.0}) {
    const Eigen::Vector3d centre(side * (half_width - 2.0 * ball_radius), -0.11 * radius_m,
                                 ball_radius);
    dome.scene.spheres.push_back({centre, ball_radius, 1});
    dome.balls.push_back({centre, ball_radius});
  }
  return dome;
}

NearRtiRenderer::NearRtiRenderer(const NearRtiDome& dome)
    : dome_(dome),
      backdrop_(dome.stage, dome.scene, 1),
      // A 5 mm LED mirrored in a 4 cm sphere is a spot under a tenth of a pixel across: 32x32
      // samples per pixel meet it.
      mirrors_(dome.balls, dome.stage.camera, 32) {}

namespace {

// Toward the camera from p (unit).
Eigen::Vector3d toward_camera(const CameraSpec& camera, const Eigen::Vector3d& p) {
  if (camera.fov_y_deg <= 0) return {0, 0, 1};
  return (Eigen::Vector3d(0, 0, camera.distance_m) - p).normalized();
}

// Where the camera sees a point (continuous pixels, x right, y down).
Eigen::Vector2d project(const CameraSpec& camera, const Eigen::Vector3d& p) {
  double scale = camera.height / camera.ortho_height_m;  // Pixels per metre at p.
  if (camera.fov_y_deg > 0) {
    scale = 0.5 * camera.height / std::tan(0.5 * camera.fov_y_deg * std::numbers::pi / 180) /
            (camera.distance_m - p.z());
  }
  return {0.5 * camera.width + scale * p.x(), 0.5 * camera.height - scale * p.y()};
}

// Where a ball mirrors a point toward the camera: the normal halves the view and the way to the
// point, found by fixed-point iteration (the ball is small beside both distances).
Eigen::Vector3d mirror_point(const MirrorBall& ball, const Eigen::Vector3d& point,
                             const CameraSpec& camera) {
  Eigen::Vector3d n =
      (toward_camera(camera, ball.center) + (point - ball.center).normalized()).normalized();
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d p = ball.center + ball.radius_m * n;
    n = (toward_camera(camera, p) + (point - p).normalized()).normalized();
  }
  return ball.center + ball.radius_m * n;
}

// The fraction of a unit-flux Gaussian spot (sigma in pixels) centred at c that falls in pixel i.
double pixel_share(int i, double c, double sigma) {
  const auto cdf = [&](double x) { return 0.5 * std::erfc(-(x - c) / (sigma * std::sqrt(2.0))); };
  return cdf(i + 1.0) - cdf(double(i));
}

}  // namespace

Image NearRtiRenderer::render(int led_index) {
  Image image = backdrop_.one_light_image(led_index);
  const Led& led = dome_.stage.leds[size_t(led_index)];
  const Image mirror = mirrors_.render_led(led, 0.005, 0.6);
  // The supersampled spot gives each ball's flux, but sits wherever its pixel is: a lens spreads
  // it around the true mirror point, so it is put back there, a Gaussian of 0.5 px.
  const CameraSpec& camera = dome_.stage.camera;
  const Eigen::Vector3d led_position = *led.distance_m * led.dir_in_stage.normalized();
  constexpr double kSpotSigmaPx = 0.5;
  for (const MirrorBall& ball : dome_.balls) {
    const Eigen::Vector2d centre = project(camera, ball.center);
    const double cx = centre.x(), cy = centre.y();
    const double r =
        (project(camera, ball.center + Eigen::Vector3d(ball.radius_m, 0, 0)) - centre).norm() *
            1.2 +
        2;
    Eigen::Vector3d flux = Eigen::Vector3d::Zero();
    for (int y = std::max(0, int(cy - r)); y <= std::min(camera.height - 1, int(cy + r)); ++y) {
      for (int x = std::max(0, int(cx - r)); x <= std::min(camera.width - 1, int(cx + r)); ++x) {
        for (int c = 0; c < 3; ++c) flux[c] += mirror.at(x, y, c);
      }
    }
    const Eigen::Vector2d spot = project(camera, mirror_point(ball, led_position, camera));
    const double px = spot.x(), py = spot.y();
    for (int y = std::max(0, int(py) - 3); y <= std::min(camera.height - 1, int(py) + 3); ++y) {
      for (int x = std::max(0, int(px) - 3); x <= std::min(camera.width - 1, int(px) + 3); ++x) {
        const double share = pixel_share(x, px, kSpotSigmaPx) * pixel_share(y, py, kSpotSigmaPx);
        for (int c = 0; c < 3; ++c) image.at(x, y, c) += float(flux[c] * share);
      }
    }
  }
  return image;
}

}  // namespace ls::sim
