#include "physics/sphere.h"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace ls::physics {

Eigen::Matrix3d rotation_about_y(double angle_rad) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  Eigen::Matrix3d r;
  r << c, 0, s, 0, 1, 0, -s, 0, c;
  return r;
}

std::vector<Eigen::Vector3d> disc_directions(const Eigen::Vector3d& dir, double radius_rad,
                                             int count) {
  const Eigen::Vector3d centre = dir.normalized();
  const Eigen::Vector3d helper =
      std::abs(centre.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d u = centre.cross(helper).normalized(), v = centre.cross(u);
  const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
  std::vector<Eigen::Vector3d> dirs;
  for (int i = 0; i < count; ++i) {
    const double r = std::tan(radius_rad) * std::sqrt((i + 0.5) / count);
    const double a = golden_angle * i;
    dirs.push_back((centre + r * (std::cos(a) * u + std::sin(a) * v)).normalized());
  }
  return dirs;
}

}  // namespace ls::physics
