#include "sim/rti_scenes.h"

#include <string>
#include <vector>

namespace ls::sim {

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

}  // namespace ls::sim
