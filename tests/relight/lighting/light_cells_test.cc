#include "relight/lighting/light_cells.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <random>
#include <vector>

#include "lightstage/stage.h"

namespace {

using ls::Image;
using ls::physics::EnvironmentMap;
using ls::relight::integrate_environment;
using ls::relight::LightCells;
using ls::relight::LightWeights;

double total_sr(const LightCells& cells) {
  double sum = cells.uncovered_sr;
  for (double s : cells.solid_angle_sr) sum += s;
  return sum;
}

std::vector<Eigen::Vector3d> random_directions(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  std::vector<Eigen::Vector3d> dirs;
  for (int i = 0; i < count; ++i) {
    dirs.push_back(Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized());
  }
  return dirs;
}

std::vector<Eigen::Vector3d> axis_directions() {
  return {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
}

// Brute force: the index of the LED with the largest dot product (lowest index on ties).
int nearest_brute_force(const std::vector<Eigen::Vector3d>& dirs, const Eigen::Vector3d& d) {
  int best = 0;
  for (int l = 1; l < int(dirs.size()); ++l) {
    if (d.dot(dirs[l]) > d.dot(dirs[best])) best = l;
  }
  return best;
}

// (Compute and integrate times are measured in microbench/bench_relight.cc, not asserted here.)
TEST(LightCellsTest, DefaultDomeSumsTo4PiAndEveryCellLiesInItsCoverageCap) {
  const std::vector<Eigen::Vector3d> dirs = ls::default_stage().led_directions();
  ASSERT_GT(dirs.size(), 100u);
  const LightCells cells = LightCells::compute(dirs, 0.0, /*resolution=*/1024);
  EXPECT_NEAR(total_sr(cells), 4 * std::numbers::pi, 1e-6 * 4 * std::numbers::pi);
  EXPECT_NEAR(cells.coverage_radius_rad, ls::max_nearest_neighbour_angle(dirs), 0.0);
  // The dome stops about 11.5 degrees below the horizon: most of the lower hemisphere is open.
  EXPECT_GT(cells.uncovered_sr, 0.5 * 2 * std::numbers::pi);
  EXPECT_LT(cells.uncovered_sr, 2 * std::numbers::pi);
  // A cell holds directions within the coverage radius of its own LED (the nearest one), so it
  // lies inside that spherical cap: at most 2 pi (1 - cos r) sr, up to the grid's quadrature error
  // (1%).
  const double cap_sr = 2 * std::numbers::pi * (1 - std::cos(cells.coverage_radius_rad));
  for (size_t l = 0; l < dirs.size(); ++l) {
    EXPECT_GT(cells.solid_angle_sr[l], 0.0) << "LED " << l;  // Every LED stands for something.
    EXPECT_LT(cells.solid_angle_sr[l], 1.01 * cap_sr) << "LED " << l;
  }
  // The covered sphere is at least what the caps of the LEDs reach minus their overlaps, and at
  // most the sum of the caps.
  EXPECT_LT(4 * std::numbers::pi - cells.uncovered_sr, dirs.size() * cap_sr);

  std::vector<double> sorted = cells.solid_angle_sr;
  std::sort(sorted.begin(), sorted.end());
  std::cout << "default dome: " << dirs.size()
            << " LEDs, cell solid angle min/median/max = " << sorted.front() << " / "
            << sorted[sorted.size() / 2] << " / " << sorted.back() << " sr (cap " << cap_sr
            << " sr), uncovered " << cells.uncovered_sr << " sr, coverage radius "
            << cells.coverage_radius_rad * 180 / std::numbers::pi << " deg\n";
  ::testing::Test::RecordProperty("cell_sr_min", std::to_string(sorted.front()));
  ::testing::Test::RecordProperty("cell_sr_median", std::to_string(sorted[sorted.size() / 2]));
  ::testing::Test::RecordProperty("cell_sr_max", std::to_string(sorted.back()));
}

TEST(LightCellsTest, RandomPointSetsSumTo4Pi) {
  for (int count : {1, 2, 5, 37, 150, 400}) {
    for (double coverage_rad : {0.0, 0.3, 4.0}) {
      const LightCells cells =
          LightCells::compute(random_directions(count, 11 + count), coverage_rad,
                              /*resolution=*/256, /*supersample=*/3);
      EXPECT_NEAR(total_sr(cells), 4 * std::numbers::pi, 1e-6 * 4 * std::numbers::pi)
          << count << " " << coverage_rad;
      if (coverage_rad > std::numbers::pi) {
        EXPECT_EQ(cells.uncovered_sr, 0.0);
      }
    }
  }
}

// The bucket grid that accelerates the nearest-LED search must not change any assignment.
TEST(LightCellsTest, MatchesBruteForceAssignment) {
  for (int count : {3, 60, 150}) {
    const std::vector<Eigen::Vector3d> dirs = random_directions(count, 5 * count);
    const int resolution = 128;
    const LightCells cells = LightCells::compute(dirs, 4.0, resolution, /*supersample=*/1);
    const EnvironmentMap grid(Image(resolution, resolution / 2, 3));
    std::vector<double> expected(count, 0.0);
    for (int y = 0; y < grid.height(); ++y) {
      for (int x = 0; x < grid.width(); ++x) {
        expected[nearest_brute_force(dirs, grid.pixel_direction(x, y))] +=
            grid.pixel_solid_angle_sr(y);
      }
    }
    for (int l = 0; l < count; ++l) {
      EXPECT_NEAR(cells.solid_angle_sr[l], expected[l], 1e-12) << "LED " << l << " of " << count;
    }
  }
}

TEST(LightCellsTest, SixAxesGetEqualCells) {
  const LightCells cells = LightCells::compute(axis_directions(), 0.0, /*resolution=*/1024);
  EXPECT_NEAR(cells.coverage_radius_rad, std::numbers::pi / 2, 1e-12);
  EXPECT_EQ(cells.uncovered_sr, 0.0);
  for (double s : cells.solid_angle_sr)
    EXPECT_NEAR(s, 4 * std::numbers::pi / 6, 1e-3 * 4 * std::numbers::pi / 6);
}

// LEDs every degree round the horizon and rings above it, coverage 10 degrees: what is left
// uncovered is the cap below -10 degrees elevation (less the thin scallops between horizon LEDs).
TEST(LightCellsTest, HemisphereDomeLeavesTheLowerCapUncovered) {
  std::vector<Eigen::Vector3d> dirs;
  for (int ring = 0; ring <= 10; ++ring) {
    const double elevation = ring * 8.0 * std::numbers::pi / 180;
    const int count = std::max(1, int(std::ceil(360 * std::cos(elevation))));
    for (int k = 0; k < count; ++k) {
      const double azimuth = 2 * std::numbers::pi * k / count;
      dirs.emplace_back(std::cos(elevation) * std::sin(azimuth), std::sin(elevation),
                        std::cos(elevation) * std::cos(azimuth));
    }
  }
  const double coverage_rad = 10.0 * std::numbers::pi / 180;
  const LightCells cells = LightCells::compute(dirs, coverage_rad, /*resolution=*/1024);
  const double lower_cap_sr = 2 * std::numbers::pi * (1 - std::sin(coverage_rad));
  EXPECT_NEAR(cells.uncovered_sr, lower_cap_sr, 2e-3 * lower_cap_sr);
  EXPECT_NEAR(total_sr(cells), 4 * std::numbers::pi, 1e-6 * 4 * std::numbers::pi);
}

EnvironmentMap constant_map(int width, const Eigen::Vector3f& value) {
  Image image(width, width / 2, 3);
  for (size_t i = 0; i < image.num_pixels(); ++i) {
    for (int c = 0; c < 3; ++c) image.pixels[3 * i + c] = value[c];
  }
  return EnvironmentMap(image);
}

TEST(LightCellsTest, ConstantMapGivesRadianceTimesCellSolidAngle) {
  const std::vector<Eigen::Vector3d> dirs = ls::default_stage().led_directions();
  const Eigen::Vector3f c(0.5f, 1.0f, 2.0f);
  for (int supersample : {1, 2, 3}) {
    const LightCells cells = LightCells::compute(dirs, 0.0, /*resolution=*/256, supersample);
    const LightWeights weights =
        integrate_environment(constant_map(256, c), dirs, 0.0, 0.0, {}, supersample);
    ASSERT_EQ(weights.irradiance_rgb.size(), 3 * dirs.size());
    for (size_t l = 0; l < dirs.size(); ++l) {
      for (int ch = 0; ch < 3; ++ch) {
        EXPECT_NEAR(weights.irradiance_rgb[3 * l + ch], c[ch] * cells.solid_angle_sr[l],
                    1e-6 * c[ch] * cells.solid_angle_sr[l]);
      }
    }
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_NEAR(weights.uncovered_irradiance_rgb[ch], c[ch] * cells.uncovered_sr, 1e-9);
      EXPECT_NEAR(weights.total_irradiance_rgb[ch], c[ch] * 4 * std::numbers::pi, 1e-9);
    }
    EXPECT_NEAR(weights.uncovered_fraction(), cells.uncovered_sr / (4 * std::numbers::pi), 1e-9);
  }
}

// A map that is 1/Omega_l inside LED l's cell (by the same rule: nearest LED, within the coverage
// radius) and 0 elsewhere. The last LED is on the lowest ring, where coverage cuts its cell.
TEST(LightCellsTest, IndicatorMapOfOneCellGivesUnitIrradianceToThatLedOnly) {
  const std::vector<Eigen::Vector3d> dirs = ls::default_stage().led_directions();
  const double cos_coverage = std::cos(ls::max_nearest_neighbour_angle(dirs));
  const int width = 512;
  const EnvironmentMap grid(Image(width, width / 2, 3));
  const auto in_cell = [&](int x, int y, int target) {
    const Eigen::Vector3d d = grid.pixel_direction(x, y);
    const int l = nearest_brute_force(dirs, d);
    return l == target && d.dot(dirs[l]) >= cos_coverage;
  };
  for (int target : {0, int(dirs.size()) / 2, int(dirs.size()) - 1}) {
    double cell_sr = 0;
    for (int y = 0; y < grid.height(); ++y) {
      for (int x = 0; x < width; ++x) {
        if (in_cell(x, y, target)) cell_sr += grid.pixel_solid_angle_sr(y);
      }
    }
    ASSERT_GT(cell_sr, 0.0);
    Image image(width, width / 2, 3, 0.0f);
    for (int y = 0; y < grid.height(); ++y) {
      for (int x = 0; x < width; ++x) {
        if (in_cell(x, y, target)) {
          for (int c = 0; c < 3; ++c) image.at(x, y, c) = float(1.0 / cell_sr);
        }
      }
    }
    const EnvironmentMap map(image);
    // One sample per pixel, at its centre: the rule that built the map, so exact.
    // Supersampled: boundary pixels split between neighbours, so approximately.
    for (auto [supersample, tol] : {std::pair{1, 1e-5}, std::pair{2, 0.05}, std::pair{4, 0.05}}) {
      const LightWeights w = integrate_environment(map, dirs, 0.0, 0.0, {}, supersample);
      double others = 0;
      for (size_t l = 0; l < dirs.size(); ++l) {
        if (int(l) != target) others += w.irradiance_rgb[3 * l + 1];
      }
      EXPECT_NEAR(w.irradiance_rgb[3 * target + 1], 1.0, tol) << "LED " << target;
      EXPECT_NEAR(others, 0.0, tol) << "LED " << target;
      EXPECT_NEAR(w.uncovered_irradiance_rgb[1], 0.0, tol);
    }
  }
}

// A spot behind the scene (-Z), map rotated by +90 degrees about +Y: the spot moves to -X.
TEST(LightCellsTest, RotationMovesLightToTheRotatedLed) {
  const std::vector<Eigen::Vector3d> dirs = axis_directions();
  const int minus_x = 1, minus_z = 5, plus_x = 0;
  Image image(256, 128, 3, 0.0f);
  const EnvironmentMap probe(Image(256, 128, 3));
  for (int y = 0; y < 128; ++y) {
    for (int x = 0; x < 256; ++x) {
      if (probe.pixel_direction(x, y).z() < -0.9) image.at(x, y, 0) = 1.0f;
    }
  }
  const EnvironmentMap map(image);
  const LightWeights unrotated = integrate_environment(map, dirs);
  const LightWeights rotated = integrate_environment(map, dirs, 90.0);
  const LightWeights back = integrate_environment(map, dirs, -90.0);
  EXPECT_GT(unrotated.irradiance_rgb[3 * minus_z], 0.1);
  EXPECT_EQ(unrotated.irradiance_rgb[3 * minus_x], 0.0f);
  EXPECT_NEAR(rotated.irradiance_rgb[3 * minus_x], unrotated.irradiance_rgb[3 * minus_z], 1e-6);
  EXPECT_EQ(rotated.irradiance_rgb[3 * minus_z], 0.0f);
  EXPECT_NEAR(back.irradiance_rgb[3 * plus_x], unrotated.irradiance_rgb[3 * minus_z], 1e-6);
  // Consistent with the map's own rotated lookup.
  EXPECT_GT(map.radiance_toward({-1, 0, 0}, 90.0)[0], 0.9f);
}

// A dead LED's cell goes to its valid neighbours; coverage (a property of the dome) is unchanged.
TEST(LightCellsTest, DeadLedsCellsGoToNearestValidLed) {
  const std::vector<Eigen::Vector3d> dirs = axis_directions();
  const EnvironmentMap map = constant_map(256, Eigen::Vector3f(1, 1, 1));
  std::vector<bool> valid(6, true);
  valid[2] = false;  // +Y.
  const LightWeights all = integrate_environment(map, dirs);
  const LightWeights some = integrate_environment(map, dirs, 0.0, 0.0, valid);
  EXPECT_EQ(some.irradiance_rgb[3 * 2], 0.0f);
  EXPECT_NEAR(some.irradiance_rgb[3 * 3], all.irradiance_rgb[3 * 3], 1e-6);  // -Y: not adjacent.
  for (int l : {0, 1, 4, 5}) {
    EXPECT_NEAR(some.irradiance_rgb[3 * l], all.irradiance_rgb[3 * l] * 1.25, 1e-3) << l;
  }
  EXPECT_EQ(some.uncovered_irradiance_rgb, all.uncovered_irradiance_rgb);

  // No valid LED at all: everything is uncovered, nothing is lost.
  const LightWeights none = integrate_environment(map, dirs, 0.0, 0.0, std::vector<bool>(6, false));
  EXPECT_NEAR(none.uncovered_fraction(), 1.0, 1e-12);
}

// A rotation sequence under L(w) = a + b w.x, per channel: the linear term integrates to zero over
// the sphere, so the map's total is 4 pi a at every rotation; and rotating by 180 degrees about +Y
// flips w.x, so the irradiance at 0 and at 180 degrees adds up to 2 a times the cell's solid angle,
// LED by LED. A full turn gives back the unrotated weights.
TEST(LightCellsTest, RotationSequenceConservesTheMapAndOppositeRotationsCancelTheGradient) {
  const std::vector<Eigen::Vector3d> dirs = ls::default_stage().led_directions();
  const Eigen::Vector3d a(1, 2, 3), b(0.9, -1.5, 2.5);
  const int width = 512;
  Image image(width, width / 2, 3);
  const EnvironmentMap probe(Image(width, width / 2, 3));
  for (int y = 0; y < width / 2; ++y) {
    for (int x = 0; x < width; ++x) {
      const double wx = probe.pixel_direction(x, y).x();
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = float(a[c] + b[c] * wx);
    }
  }
  const EnvironmentMap map(image);
  const LightCells cells = LightCells::compute(dirs, 0.0, width);
  std::vector<LightWeights> turns;
  for (int i = 0; i <= 10; ++i) turns.push_back(integrate_environment(map, dirs, 36.0 * i));
  double worst_total = 0, worst_sum = 0, worst_pair = 0, worst_turn = 0;
  for (const LightWeights& w : turns) {
    for (int c = 0; c < 3; ++c) {
      worst_total = std::max(
          worst_total, std::abs(w.total_irradiance_rgb[c] / (4 * std::numbers::pi * a[c]) - 1));
      double sum = w.uncovered_irradiance_rgb[c];
      for (size_t l = 0; l < dirs.size(); ++l) sum += w.irradiance_rgb[3 * l + c];
      worst_sum = std::max(worst_sum, std::abs(sum / w.total_irradiance_rgb[c] - 1));
    }
  }
  for (size_t l = 0; l < dirs.size(); ++l) {
    for (int c = 0; c < 3; ++c) {
      const double expected = 2 * a[c] * cells.solid_angle_sr[l];
      const double pair = turns[0].irradiance_rgb[3 * l + c] + turns[5].irradiance_rgb[3 * l + c];
      worst_pair = std::max(worst_pair, std::abs(pair / expected - 1));
      worst_turn = std::max(worst_turn, double(std::abs(turns[10].irradiance_rgb[3 * l + c] -
                                                        turns[0].irradiance_rgb[3 * l + c])) /
                                            turns[0].irradiance_rgb[3 * l + c]);
    }
  }
  std::cout << "rotation sequence: total vs 4 pi a " << worst_total
            << ", cells + uncovered vs total " << worst_sum << ", E(0) + E(180) vs 2 a Omega "
            << worst_pair << ", full turn " << worst_turn << " (worst relative)\n";
  // Measured 4.6e-10, 2.5e-9, 8.5e-8 and 0: the lat-long quadrature is exact for w.x (its
  // azimuthal sum cancels), so only rounding is left; the bounds allow float accumulation.
  EXPECT_LT(worst_total, 1e-6);
  EXPECT_LT(worst_sum, 1e-6);  // Every sample goes to one LED or to "uncovered".
  EXPECT_LT(worst_pair, 1e-6);
  EXPECT_LT(worst_turn, 1e-6);
}

TEST(LightCellsTest, MaxNearestNeighbourAngle) {
  EXPECT_NEAR(ls::max_nearest_neighbour_angle(axis_directions()), std::numbers::pi / 2, 1e-12);
  EXPECT_EQ(ls::max_nearest_neighbour_angle({{0, 1, 0}}), std::numbers::pi);
  const auto at_angle = [](double rad) { return Eigen::Vector3d(std::sin(rad), std::cos(rad), 0); };
  EXPECT_NEAR(ls::max_nearest_neighbour_angle({at_angle(0), at_angle(0.1), at_angle(0.3)}), 0.2,
              1e-12);
}

}  // namespace
