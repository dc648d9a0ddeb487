#pragma once
// Unit directions (LEDs on a dome) in a k-d tree (nanoflann): the nearest neighbour of each, and
// the neighbours within an angle, in about log N each. Scanning all pairs is O(N^2): minutes at
// the 100,000 LEDs a stage file may hold.
#include <Eigen/Core>
#include <memory>
#include <optional>
#include <vector>

namespace ls {

class DirectionIndex {
 public:
  // unit_dirs: unit vectors (the caller normalises), kept by reference for the index's life.
  explicit DirectionIndex(const std::vector<Eigen::Vector3d>& unit_dirs);
  ~DirectionIndex();
  DirectionIndex(const DirectionIndex&) = delete;
  DirectionIndex& operator=(const DirectionIndex&) = delete;

  // Angle (radians) from direction i to its nearest other direction; pi when it is alone.
  double nearest_other_angle(int i) const;
  // Angle (radians) from the unit vector d to the nearest direction; pi when there is none.
  double nearest_angle(const Eigen::Vector3d& d) const;
  // Index of the direction nearest to the unit vector d; -1 when there is none.
  int nearest(const Eigen::Vector3d& d) const;
  // Indices of the directions within angle_rad of the unit vector d, nearest first.
  std::vector<int> within(const Eigen::Vector3d& d, double angle_rad) const;

 private:
  struct Tree;
  const std::vector<Eigen::Vector3d>& dirs_;
  std::unique_ptr<Tree> tree_;
};

// The angle between two directions in radians (any lengths, non-zero): atan2 of |a x b| and a . b,
// accurate at small angles where acos of the dot product is not.
double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

// v scaled to unit length, or nullopt when it has no direction: a non-finite component, or a
// length of at most min_length. The length by stableNorm: the squares of components near the
// largest double overflow norm(), and normalized() then gives 0.
std::optional<Eigen::Vector3d> unit_vector(const Eigen::Vector3d& v, double min_length = 1e-9);

// The largest angle from any direction to its nearest other one (pi for fewer than two): the
// widest gap of a dome's sampling. Directions need not be unit length (non-zero, finite).
double max_nearest_neighbour_angle(const std::vector<Eigen::Vector3d>& dirs);

}  // namespace ls
