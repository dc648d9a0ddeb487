#pragma once
// Lighting as a set of distant lights: unit directions toward the light in the stage frame, each
// with its irradiance at normal incidence per channel (radiance x solid angle of the patch it
// stands for). What the fitted models (relight/fit/model_render.h) and the compact fields
// (relight/lighting/compact_field.h) are lit by. An environment map becomes such a set either one
// light per LED cell (led_cells: the lights field relighting uses) or one per texel of a coarse
// lat-long grid (environment).
#include <Eigen/Core>
#include <vector>

#include "physics/envmap.h"
#include "relight/lighting/light_cells.h"

namespace ls::relight {

// How environment() samples a map.
struct EnvironmentSampling {
  int directions_width =
      64;  // Lat-long grid of directions_width x directions_width/2 (even, >= 4).
  // When set, only directions within coverage_radius_rad (<= 0: the largest nearest-neighbour angle
  // between LEDs, as light_cells.h) of one of these LEDs are kept. The fit saw light only from the
  // dome, so outside it a lobe is extrapolated: a fit poorly constrained at a rim pixel can carry a
  // lobe aimed below the dome that no measurement bounds.
  std::vector<Eigen::Vector3d> covered_by_leds;
  double coverage_radius_rad = 0.0;
};

struct LightingForModels {
  std::vector<Eigen::Vector3f> dirs_in_stage;   // Unit, toward the light.
  std::vector<Eigen::Vector3f> irradiance_rgb;  // At normal incidence, per direction.

  // The map (rotated by rotation_deg about +Y, as for field relighting) box-filtered onto the
  // sampling's grid; black texels are dropped.
  static LightingForModels environment(const physics::EnvironmentMap& map,
                                       double rotation_deg = 0.0,
                                       const EnvironmentSampling& sampling = {});
  // One light per LED: direction led_dirs[l], irradiance weights.irradiance_rgb[3l..3l+2]
  // (integrate_environment); LEDs with zero weight (dead ones) are dropped.
  static LightingForModels led_cells(const std::vector<Eigen::Vector3d>& led_dirs,
                                     const LightWeights& weights);
  // A single distant light: irradiance_rgb at normal incidence from dir_in_stage.
  static LightingForModels directional(const Eigen::Vector3d& dir_in_stage,
                                       const Eigen::Vector3d& irradiance_rgb);
};

}  // namespace ls::relight
