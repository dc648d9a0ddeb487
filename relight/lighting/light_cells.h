#pragma once
// Each LED stands for the directions nearer to it than to any other LED: its spherical Voronoi cell
// Omega_l, restricted to the dome's coverage (directions within coverage_radius of some LED). What
// lies outside every cell (below the stage, through holes) is "uncovered" and is reported.
// E_l = integral over Omega_l of L(w) dw is the irradiance LED l must stand in for.
#include <Eigen/Core>
#include <vector>

#include "lightstage/direction_index.h"  // max_nearest_neighbour_angle: the default coverage.
#include "physics/envmap.h"

namespace ls::relight {

struct LightCells {
  std::vector<double> solid_angle_sr;  // Per LED; sum + uncovered_sr == 4 pi.
  double uncovered_sr = 0.0;
  double coverage_radius_rad = 0.0;

  // Cells computed by exact-area quadrature on a lat-long grid of resolution x resolution/2 with
  // `supersample`^2 samples per pixel. coverage_radius_rad <= 0 picks the largest nearest-neighbour
  // angle between LEDs.
  static LightCells compute(const std::vector<Eigen::Vector3d>& led_dirs,
                            double coverage_radius_rad = 0.0, int resolution = 2048,
                            int supersample = 2);
};

struct LightWeights {
  std::vector<float> irradiance_rgb;                  // 3 per LED: E_l per channel.
  Eigen::Vector3d uncovered_irradiance_rgb{0, 0, 0};  // Light of the map no LED stands for.
  Eigen::Vector3d total_irradiance_rgb{0, 0, 0};      // Whole map: covered + uncovered.
  double uncovered_fraction() const;                  // Of total luminance.
};

// Integrates the map rotated by rotation_deg about +Y over each LED's cell. `valid` (optional, one
// per LED) excludes dead LEDs: their cells go to the nearest valid LED.
LightWeights integrate_environment(const physics::EnvironmentMap& map,
                                   const std::vector<Eigen::Vector3d>& led_dirs,
                                   double rotation_deg = 0.0, double coverage_radius_rad = 0.0,
                                   const std::vector<bool>& valid = {}, int supersample = 2);

}  // namespace ls::relight
