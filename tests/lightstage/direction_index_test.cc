#include "lightstage/direction_index.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "lightstage/image.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

std::vector<Eigen::Vector3d> random_directions(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  std::vector<Eigen::Vector3d> dirs;
  dirs.resize(size_t(n));
  for (auto& d : dirs) d = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
  return dirs;
}

double angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0));
}

// The k-d tree answers what scanning every pair answers.
TEST(DirectionIndex, AgreesWithScanningEveryPair) {
  const std::vector<Eigen::Vector3d> dirs = random_directions(500, 3);
  const DirectionIndex index(dirs);
  const std::vector<Eigen::Vector3d> queries = random_directions(50, 4);
  for (int i = 0; i < int(dirs.size()); ++i) {
    double nearest = std::numbers::pi;
    for (int j = 0; j < int(dirs.size()); ++j) {
      if (j != i) nearest = std::min(nearest, angle(dirs[size_t(i)], dirs[size_t(j)]));
    }
    EXPECT_NEAR(index.nearest_other_angle(i), nearest, 1e-9) << i;
  }
  for (const Eigen::Vector3d& q : queries) {
    for (const double limit : {0.0, 0.05, 0.3, std::numbers::pi}) {
      std::vector<int> expected;
      double nearest = std::numbers::pi;
      for (int j = 0; j < int(dirs.size()); ++j) {
        nearest = std::min(nearest, angle(q, dirs[size_t(j)]));
        if (angle(q, dirs[size_t(j)]) <= limit) expected.push_back(j);
      }
      std::vector<int> found = index.within(q, limit);
      std::sort(found.begin(), found.end());
      EXPECT_EQ(found, expected) << limit;
      EXPECT_NEAR(index.nearest_angle(q), nearest, 1e-9);
    }
  }
  EXPECT_NEAR(max_nearest_neighbour_angle({{0, 0, 2}, {0, 3, 0}}), std::numbers::pi / 2, 1e-12);
  EXPECT_EQ(max_nearest_neighbour_angle({{0, 1, 0}}), std::numbers::pi);
  EXPECT_TRUE(DirectionIndex(std::vector<Eigen::Vector3d>{}).within({0, 0, 1}, 1.0).empty());
}

// The stage validator allows 100,000 LEDs; `lightstage stage` summarises such a stage in about
// 2 s (scanning every pair of LEDs instead would take minutes).
TEST(DirectionIndex, TheLargestStageAFileMayHoldIsSummarised) {
  testing::TempDir dir;
  write_file_atomic(dir / "big.json",
                    R"({"name": "big", "layout": {"type": "fibonacci", "count": 100000},
                        "camera": {"backend": "sim", "width": 16, "height": 16}})");
  std::string output;
  ASSERT_EQ(testing::run_command(
                testing::cli_path().string() + " stage " + (dir / "big.json").string(), &output),
            0)
      << output;
  EXPECT_NE(output.find("LEDs: 100000"), std::string::npos) << output;
}

}  // namespace
}  // namespace ls
