#pragma once
// Directions on the unit sphere: rotations about the stage's +Y (up) and a disc of directions
// sampled evenly. Directions are in the stage frame (DESIGN.md): +Y up, unit, toward the light.
#include <Eigen/Core>
#include <vector>

namespace ls::physics {

// R_y(angle): the right-handed rotation about +Y (+Z turns toward +X for a positive angle).
Eigen::Matrix3d rotation_about_y(double angle_rad);

// `count` directions spread evenly over a uniform disc of directions (centre `dir`, angular radius
// radius_rad): sunflower (golden-angle) points, each standing for an equal area of the disc.
std::vector<Eigen::Vector3d> disc_directions(const Eigen::Vector3d& dir, double radius_rad,
                                             int count);

}  // namespace ls::physics
