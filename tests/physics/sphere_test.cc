#include "physics/sphere.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <vector>

#include "lightstage/direction_index.h"
#include "physics/envmap.h"

namespace {

using ls::angle_between;
using ls::physics::disc_directions;
using ls::physics::rotation_about_y;

// Right-handed about +Y: a quarter turn takes +Z to +X and +X to -Z; Y stays; it is a rotation.
TEST(SphereTest, RotationAboutYIsRightHanded) {
  const Eigen::Matrix3d quarter = rotation_about_y(std::numbers::pi / 2);
  EXPECT_LT((quarter * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitX()).norm(), 1e-15);
  EXPECT_LT((quarter * Eigen::Vector3d::UnitX() + Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  EXPECT_EQ(quarter * Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitY());
  const Eigen::Matrix3d r = rotation_about_y(0.7);
  EXPECT_LT((r * r.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-15);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-15);
  EXPECT_LT((rotation_about_y(0.3) * rotation_about_y(0.4) - r).norm(), 1e-15);
  // The environment map's rotation in degrees is the same rotation.
  const Eigen::Vector3d d = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  EXPECT_LT((ls::physics::rotate_about_y(d, 0.7 * 180 / std::numbers::pi) - r * d).norm(), 1e-15);
}

// Every direction lies inside the disc, unit, and the disc's centre is their mean; the sunflower
// gives each an equal share of the disc: half of them lie within the half-area radius.
TEST(SphereTest, DiscDirectionsCoverTheDiscEvenly) {
  const double radius = 0.1;
  for (const Eigen::Vector3d& centre :
       {Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0, 0, -2), Eigen::Vector3d(0.5, 0.7, 0.2)}) {
    const Eigen::Vector3d unit = centre.normalized();
    const std::vector<Eigen::Vector3d> dirs = disc_directions(centre, radius, 64);
    ASSERT_EQ(dirs.size(), 64u);
    Eigen::Vector3d mean(0, 0, 0);
    int inner = 0;
    for (const Eigen::Vector3d& d : dirs) {
      EXPECT_NEAR(d.norm(), 1.0, 1e-12);
      EXPECT_LE(angle_between(d, unit), radius + 1e-12) << centre.transpose();
      // Tangent-plane distance: the disc's area is measured there.
      inner += std::tan(angle_between(d, unit)) <= std::tan(radius) / std::sqrt(2.0);
      mean += d;
    }
    EXPECT_EQ(inner, 32) << centre.transpose();
    EXPECT_LT(angle_between(mean, unit), 0.01 * radius) << centre.transpose();
  }
  // A disc of no size is its centre, as many times as asked.
  for (const Eigen::Vector3d& d : disc_directions({1, 0, 0}, 0.0, 5)) {
    EXPECT_LT((d - Eigen::Vector3d::UnitX()).norm(), 1e-15);
  }
}

}  // namespace
