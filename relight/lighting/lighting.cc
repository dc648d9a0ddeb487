#include "relight/lighting/lighting.h"

#include <cmath>
#include <string>

#include "lightstage/errors.h"

namespace ls::relight {

LightingForModels LightingForModels::environment(const physics::EnvironmentMap& map,
                                                 double rotation_deg,
                                                 const EnvironmentSampling& sampling) {
  const int directions_width = sampling.directions_width;
  std::vector<Eigen::Vector3d> covered;
  for (const Eigen::Vector3d& d : sampling.covered_by_leds) covered.push_back(d.normalized());
  const double cos_coverage =
      std::cos(sampling.coverage_radius_rad > 0 ? sampling.coverage_radius_rad
                                                : max_nearest_neighbour_angle(covered));
  auto is_covered = [&](const Eigen::Vector3d& dir) {
    if (covered.empty()) return true;
    for (const Eigen::Vector3d& led : covered) {
      if (dir.dot(led) >= cos_coverage) return true;
    }
    return false;
  };
  if (directions_width < 4 || directions_width % 2 != 0) {
    throw InputError("model lighting: directions_width: expected an even number >= 4, got " +
                     std::to_string(directions_width));
  }
  LightingForModels out;
  for (const physics::CoarseTexel& texel :
       physics::box_filter_environment(map, directions_width, rotation_deg)) {
    if (!is_covered(texel.dir_in_stage)) continue;
    out.dirs_in_stage.push_back(texel.dir_in_stage.cast<float>());
    out.irradiance_rgb.push_back(texel.radiance_x_sr.cast<float>());
  }
  return out;
}

LightingForModels LightingForModels::led_cells(const std::vector<Eigen::Vector3d>& led_dirs,
                                               const LightWeights& weights) {
  LS_CHECK(weights.irradiance_rgb.size() == 3 * led_dirs.size(),
           "light weights for " + std::to_string(weights.irradiance_rgb.size() / 3) +
               " LEDs, directions for " + std::to_string(led_dirs.size()));
  LightingForModels out;
  for (size_t l = 0; l < led_dirs.size(); ++l) {
    const Eigen::Vector3f e(weights.irradiance_rgb[3 * l], weights.irradiance_rgb[3 * l + 1],
                            weights.irradiance_rgb[3 * l + 2]);
    if (!(e.maxCoeff() > 0)) continue;
    out.dirs_in_stage.push_back(led_dirs[l].normalized().cast<float>());
    out.irradiance_rgb.push_back(e);
  }
  return out;
}

LightingForModels LightingForModels::directional(const Eigen::Vector3d& dir_in_stage,
                                                 const Eigen::Vector3d& irradiance_rgb) {
  const double norm = dir_in_stage.norm();
  if (!(std::isfinite(norm) && norm > 0)) {
    throw InputError("directional light: direction: expected a non-zero finite vector");
  }
  if (!(irradiance_rgb.allFinite() && irradiance_rgb.minCoeff() >= 0)) {
    throw InputError("directional light: irradiance: expected finite values >= 0");
  }
  LightingForModels out;
  out.dirs_in_stage.push_back((dir_in_stage / norm).cast<float>());
  out.irradiance_rgb.push_back(irradiance_rgb.cast<float>());
  return out;
}

}  // namespace ls::relight
