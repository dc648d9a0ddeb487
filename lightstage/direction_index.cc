#include "lightstage/direction_index.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <nanoflann.hpp>
#include <numbers>

namespace ls {

namespace {

// Between unit vectors the straight-line (chord) distance is 2 sin(angle / 2): nearest by chord
// is nearest by angle.
double angle_of_chord(double chord) { return 2 * std::asin(std::clamp(chord / 2, 0.0, 1.0)); }

}  // namespace

struct DirectionIndex::Tree {
  // nanoflann's view of the directions (a member type, not one of this file's anonymous
  // namespace: the tree's fields would then have internal linkage in a unity build).
  struct Points {
    const std::vector<Eigen::Vector3d>& dirs;
    size_t kdtree_get_point_count() const { return dirs.size(); }
    double kdtree_get_pt(size_t i, size_t axis) const { return dirs[i][int(axis)]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const {
      return false;
    }
  };

  explicit Tree(const std::vector<Eigen::Vector3d>& dirs) : points{dirs}, index(3, points) {
    index.buildIndex();
  }
  Points points;
  nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Points>, Points, 3,
                                      uint32_t>
      index;
};

DirectionIndex::DirectionIndex(const std::vector<Eigen::Vector3d>& unit_dirs)
    : dirs_(unit_dirs), tree_(std::make_unique<Tree>(unit_dirs)) {}

DirectionIndex::~DirectionIndex() = default;

double DirectionIndex::nearest_other_angle(int i) const {
  if (dirs_.size() < 2) return std::numbers::pi;
  uint32_t index[2];
  double distance_sq[2];
  const size_t found = tree_->index.knnSearch(dirs_[size_t(i)].data(), 2, index, distance_sq);
  // The first is i itself, unless another direction coincides with it (distance 0 either way).
  const size_t other = index[0] == uint32_t(i) ? 1 : 0;
  return other < found ? angle_of_chord(std::sqrt(distance_sq[other])) : std::numbers::pi;
}

double DirectionIndex::nearest_angle(const Eigen::Vector3d& d) const {
  if (dirs_.empty()) return std::numbers::pi;
  uint32_t index = 0;
  double distance_sq = 0;
  tree_->index.knnSearch(d.data(), 1, &index, &distance_sq);
  return angle_of_chord(std::sqrt(distance_sq));
}

int DirectionIndex::nearest(const Eigen::Vector3d& d) const {
  if (dirs_.empty()) return -1;
  uint32_t index = 0;
  double distance_sq = 0;
  tree_->index.knnSearch(d.data(), 1, &index, &distance_sq);
  return int(index);
}

std::vector<int> DirectionIndex::within(const Eigen::Vector3d& d, double angle_rad) const {
  const double chord = 2 * std::sin(std::clamp(angle_rad, 0.0, std::numbers::pi) / 2);
  std::vector<std::pair<uint32_t, double>> matches;
  // A hair over the radius: an angle exactly at the limit is in.
  tree_->index.radiusSearch(d.data(), chord * chord * (1 + 1e-12), matches,
                            nanoflann::SearchParams(32, 0, true));
  std::vector<int> out;
  out.reserve(matches.size());
  for (const auto& [index, distance_sq] : matches) out.push_back(int(index));
  return out;
}

double max_nearest_neighbour_angle(const std::vector<Eigen::Vector3d>& dirs) {
  if (dirs.size() < 2) return std::numbers::pi;  // One LED (or none) stands for the whole sphere.
  std::vector<Eigen::Vector3d> unit(dirs.size());
  for (size_t i = 0; i < dirs.size(); ++i) unit[i] = dirs[i].normalized();
  const DirectionIndex index(unit);
  double worst = 0;
  for (int i = 0; i < int(unit.size()); ++i) worst = std::max(worst, index.nearest_other_angle(i));
  return worst;
}

std::optional<Eigen::Vector3d> unit_vector(const Eigen::Vector3d& v, double min_length) {
  const double length = v.stableNorm();
  if (!v.allFinite() || !(length > min_length) || !std::isfinite(length)) return std::nullopt;
  // Unit already, to rounding: kept as it is, so that a direction read back from a file it was
  // written to (a resumed session's stage) is the same bits, not renormalised an ulp away.
  if (std::abs(length - 1) <= 4 * std::numeric_limits<double>::epsilon()) return v;
  return v / length;
}

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

}  // namespace ls
