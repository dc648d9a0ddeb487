#pragma once
// Ground truth for accuracy tests: the scene lit directly by an environment map, integrated with
// the true BRDFs and visibility by dense quadrature over the map (no LEDs involved):
//   L_o(x) = sum over map texels (box-filtered to `directions_width` x /2) of L(w) f_r(w, w_o) cos
//   V dw
#include <Eigen/Core>
#include <vector>

#include "lightstage/image.h"
#include "lightstage/stage.h"
#include "physics/envmap.h"
#include "sim/scene.h"

namespace ls::sim {

struct GroundTruthOptions {
  int directions_width = 256;  // Quadrature grid: directions_width x directions_width/2 texels.
  double rotation_deg = 0.0;
  // When set, only directions within coverage_radius_rad of one of these LEDs are integrated, so
  // the truth covers what the dome covers (the uncovered rest is reported by
  // integrate_environment).
  std::vector<Eigen::Vector3d> covered_by_leds;
  double coverage_radius_rad = 0.0;
  // 1 (default): visibility is traced for every texel, exactly. n > 1 is an opt-in approximation
  // for quick previews: visibility is traced at the corners of blocks of n x n texels, and a block
  // whose four corners agree takes that answer for all its texels. It misses shadow detail smaller
  // than a block (n = 4 at 256 directions: 5.6 deg), notably penumbrae of small sources.
  int visibility_block = 1;
  // Scene time (seconds) at which time-varying materials are evaluated (sim/time_varying.h).
  double scene_time_s = 0.0;
};

Image render_ground_truth(const Scene& scene, const CameraSpec& camera,
                          const physics::EnvironmentMap& map, const GroundTruthOptions& options);
// The scene as it is at scene time `time_s` (seconds); overrides options.scene_time_s.
Image render_ground_truth(const Scene& scene, const CameraSpec& camera,
                          const physics::EnvironmentMap& map, const GroundTruthOptions& options,
                          double time_s);

// The share of a uniform disc of directions (centre `dir` in the stage frame, angular radius
// radius_rad) that each pixel's surface point sees unoccluded, by `samples` directions spread
// evenly over the disc (a sunflower pattern): 1 channel, 0 where nothing is hit. The visibility a
// source renderer would need to be exact (relight::add_bright_source takes it to bound the error
// of its own, interpolated from the LEDs' shadows).
Image render_source_visibility(const Scene& scene, const CameraSpec& camera,
                               const Eigen::Vector3d& dir, double radius_rad, int samples = 64);

}  // namespace ls::sim
