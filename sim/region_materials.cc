#include "sim/region_materials.h"

#include <string>

namespace ls::sim {

physics::brdf::Material region_material(int region) {
  physics::brdf::Material m;
  switch (region) {
    case kMatte:
      m.albedo = {0.75, 0.6, 0.45};
      break;
    case kRough:
      m.diffuse = physics::brdf::DiffuseModel::kOrenNayar;
      m.albedo = {0.6, 0.45, 0.3};
      m.sigma_rad = 30.0 / (180.0 / physics::brdf::kPi);  // As the tests have always computed it.
      break;
    default:
      m.albedo = {0.55, 0.15, 0.1};
      m.specular = physics::brdf::SpecularModel::kTorranceSparrow;
      m.ks = {0.35, 0.35, 0.35};
      m.roughness = 0.2;
      break;
  }
  return m;
}

void add_region_materials(Scene& scene) {
  for (int r = kMatte; r <= kGlossy; ++r) {
    SceneMaterial m;
    m.name = "region" + std::to_string(r);
    m.base = region_material(r);
    scene.materials.push_back(m);
  }
}

Scene three_region_spheres() {
  Scene scene;
  add_region_materials(scene);
  for (int r = kMatte; r <= kGlossy; ++r) {
    scene.spheres.push_back({Eigen::Vector3d(-0.9 + 0.9 * r, 0, 0), 0.4, r});
  }
  return scene;
}

}  // namespace ls::sim
