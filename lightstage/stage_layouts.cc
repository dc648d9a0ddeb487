// The generated domes (geodesic, Fibonacci), the stage built around a list of LED directions and
// the built-in dome: what a stage file's "layout" and the tests start from (lightstage/stage.h).
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "lightstage/angles.h"
#include "lightstage/errors.h"
#include "lightstage/stage.h"

namespace ls {

namespace {}  // namespace

std::vector<Eigen::Vector3d> geodesic_dome_directions(int frequency, double min_elevation_deg) {
  LS_CHECK(frequency >= 1, "geodesic frequency must be >= 1");
  // Icosahedron, rotated so that one vertex is the zenith (+Y).
  const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, phi, 0}, {1, phi, 0}, {-1, -phi, 0}, {1, -phi, 0},
                                    {0, -1, phi}, {0, 1, phi}, {0, -1, -phi}, {0, 1, -phi},
                                    {phi, 0, -1}, {phi, 0, 1}, {-phi, 0, -1}, {-phi, 0, 1}};
  const int faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                            {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                            {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                            {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  const Eigen::Quaterniond to_zenith =
      Eigen::Quaterniond::FromTwoVectors(v[0].normalized(), Eigen::Vector3d::UnitY());
  for (auto& p : v) p = to_zenith * p.normalized();

  const double min_y = std::sin(min_elevation_deg * kDegToRad) - 1e-9;
  std::vector<Eigen::Vector3d> out;
  auto add_unique = [&](const Eigen::Vector3d& d) {
    if (d.y() < min_y) return;
    for (const auto& q : out) {
      if ((q - d).squaredNorm() < 1e-16) return;
    }
    out.push_back(d);
  };
  for (const auto& f : faces) {
    const Eigen::Vector3d a = v[f[0]], b = v[f[1]], c = v[f[2]];
    for (int i = 0; i <= frequency; ++i) {
      for (int j = 0; i + j <= frequency; ++j) {
        const int k = frequency - i - j;
        add_unique(((i * a + j * b + k * c) / frequency).normalized());
      }
    }
  }
  // Deterministic order: from the zenith down, then by azimuth.
  std::sort(out.begin(), out.end(), [](const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
    if (std::abs(p.y() - q.y()) > 1e-9) return p.y() > q.y();
    return std::atan2(p.x(), -p.z()) < std::atan2(q.x(), -q.z());
  });
  return out;
}

std::vector<Eigen::Vector3d> fibonacci_dome_directions(int count, double min_elevation_deg) {
  LS_CHECK(count >= 1, "LED count must be >= 1");
  const double min_y = std::sin(min_elevation_deg * kDegToRad);
  const double golden_angle = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));
  std::vector<Eigen::Vector3d> out;
  for (int i = 0; i < count; ++i) {
    // Equal-area rings: y uniform over [min_y, 1].
    const double y = 1.0 - (i + 0.5) / count * (1.0 - min_y);
    const double r = std::sqrt(std::max(0.0, 1.0 - y * y));
    const double a = i * golden_angle;
    out.emplace_back(r * std::sin(a), y, -r * std::cos(a));
  }
  return out;
}

Stage stage_with_directions(const std::vector<Eigen::Vector3d>& dirs_in_stage) {
  Stage stage;
  stage.name = "dome-" + std::to_string(dirs_in_stage.size());
  for (size_t i = 0; i < dirs_in_stage.size(); ++i) {
    Led led;
    led.id = int(i);
    led.dir_in_stage = dirs_in_stage[i].normalized();
    stage.leds.push_back(led);
  }
  // Full scale at the middle exposure is radiance 1.0 (a white Lambertian patch facing an LED of
  // irradiance 1 has radiance 1/pi); the bracket spans x16 for highlights and shadows.
  stage.camera.radiometric_scale = 0.01;
  stage.camera.bracket = {{0.0025, 1.0}, {0.01, 1.0}, {0.04, 1.0}};
  return stage;
}

Stage default_stage() {
  Stage stage = stage_with_directions(geodesic_dome_directions(5, -11.5));
  stage.name = "default-geodesic-dome";
  return stage;
}

}  // namespace ls
