#include "relight/sources/bright_sources.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>

#include "lightstage/angles.h"
#include "relight/sources/source_render.h"

namespace {

using ls::Image;
using ls::kDegToRad;
using ls::physics::EnvironmentMap;

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.normalized().cross(b.normalized()).norm(), a.normalized().dot(b)) / kDegToRad;
}

// A uniform sky of radiance `sky` with a disc of radius radius_deg and radiance `disc` toward
// `centre`, each pixel the mean over 8 x 8 samples. Returns the disc's exact pixel integral too.
struct DiscMap {
  Image radiance;
  double disc_integral = 0;  // Of the disc's radiance over the sphere, sr x radiance.
};
DiscMap disc_map(int width, const Eigen::Vector3d& centre, double radius_deg, double disc,
                 double sky) {
  DiscMap out{Image(width, width / 2, 3)};
  const EnvironmentMap shape(Image(width, width / 2, 3));
  const double cos_r = std::cos(radius_deg * kDegToRad);
  for (int y = 0; y < width / 2; ++y) {
    for (int x = 0; x < width; ++x) {
      int inside = 0;
      for (int sy = 0; sy < 8; ++sy) {
        for (int sx = 0; sx < 8; ++sx) {
          const Eigen::Vector3d d = EnvironmentMap::direction((x + (sx + 0.5) / 8) / width,
                                                              (y + (sy + 0.5) / 8) / (width / 2));
          inside += d.dot(centre.normalized()) >= cos_r;
        }
      }
      const double share = inside / 64.0;
      for (int c = 0; c < 3; ++c) {
        out.radiance.pixels[(size_t(y) * width + x) * 3 + c] = float(sky + share * disc);
      }
      out.disc_integral += share * disc * shape.pixel_solid_angle_sr(y);
    }
  }
  return out;
}

Eigen::Vector3d sum_over_sphere(const EnvironmentMap& map) { return map.integral(); }

TEST(BrightSources, ASmallDiscIsFoundWithItsDirectionSizeAndEnergy) {
  const Eigen::Vector3d centre = Eigen::Vector3d(0.5, 0.7, 0.3).normalized();
  const DiscMap disc = disc_map(512, centre, 2.0, 400.0, 0.2);
  const EnvironmentMap map(disc.radiance);
  const auto split = ls::relight::split_bright_sources(map);
  ASSERT_EQ(split.sources.size(), 1u);
  const auto& source = split.sources[0];
  // A pixel is 0.7 deg: the centroid of a symmetric disc lands within a small part of one.
  EXPECT_LT(angle_deg(source.dir, centre), 0.1);
  EXPECT_NEAR(source.radius_rad / kDegToRad, 2.0, 0.2);
  // The sky under the disc stays in the map: the source holds the disc's own light.
  EXPECT_NEAR(source.irradiance_rgb[0], disc.disc_integral, 0.01 * disc.disc_integral);
  const double total = sum_over_sphere(map)[0];
  EXPECT_NEAR(source.energy_share, disc.disc_integral / total, 0.01);
  // Nothing is lost or made: rest + source == map.
  EXPECT_NEAR(sum_over_sphere(split.rest)[0] + source.irradiance_rgb[0], total, 1e-4 * total);
}

TEST(BrightSources, WideAreaLightsAndDimSpecksStayInTheMap) {
  // A 20-degree softbox: far wider than a few degrees, so the LED cells relight it well.
  const DiscMap box = disc_map(256, Eigen::Vector3d(0, 1, -1), 20.0, 50.0, 0.05);
  EXPECT_TRUE(ls::relight::split_bright_sources(EnvironmentMap(box.radiance)).sources.empty());
  // A speck bright per pixel but holding under 1% of the light: its ghosts would not show.
  const DiscMap speck = disc_map(256, Eigen::Vector3d(0, 1, -1), 1.0, 40.0, 0.5);
  EXPECT_TRUE(ls::relight::split_bright_sources(EnvironmentMap(speck.radiance)).sources.empty());
}

TEST(BrightSources, TwoSourcesAreBothFoundBrightestFirst) {
  const Eigen::Vector3d a = Eigen::Vector3d(0.2, 0.8, 0.5).normalized();
  const Eigen::Vector3d b = Eigen::Vector3d(-0.6, 0.5, -0.4).normalized();
  Image radiance = disc_map(512, a, 1.0, 2000.0, 0.1).radiance;
  const Image second = disc_map(512, b, 1.5, 500.0, 0.0).radiance;
  for (size_t i = 0; i < radiance.pixels.size(); ++i) radiance.pixels[i] += second.pixels[i];
  const auto split = ls::relight::split_bright_sources(EnvironmentMap(radiance));
  ASSERT_EQ(split.sources.size(), 2u);
  EXPECT_LT(angle_deg(split.sources[0].dir, a), 0.1);
  EXPECT_LT(angle_deg(split.sources[1].dir, b), 0.1);
}

// The weights of a direction in its LED triangle reproduce the direction, and they change
// continuously as it moves: a sun sweeping across the dome moves its shadows without jumps.
TEST(LedTriangle, WeightsInterpolateTheDirectionAndMoveContinuously) {
  std::vector<Eigen::Vector3d> leds;
  const int count = 151;
  const double golden = std::numbers::pi * (3 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {  // A Fibonacci hemisphere.
    const double y = 1 - (i + 0.5) / count;
    const double r = std::sqrt(1 - y * y);
    leds.emplace_back(r * std::cos(golden * i), y, r * std::sin(golden * i));
  }
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uniform(-1, 1);
  int checked = 0;
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Vector3d d(uniform(rng), std::abs(uniform(rng)) + 0.1, uniform(rng));
    d.normalize();
    const auto t = ls::relight::led_triangle(leds, {}, d, 0.3);
    ASSERT_TRUE(t.has_value());
    Eigen::Vector3d mix(0, 0, 0);
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(t->weights[size_t(k)], 0.0);
      mix += t->weights[size_t(k)] * leds[size_t(t->leds[size_t(k)])];
    }
    EXPECT_LT(angle_deg(mix, d), 1e-6);
    // A step of 0.01 degree changes no LED's weight by more than a little.
    const Eigen::Vector3d step =
        (d + 1.745e-4 * d.cross(Eigen::Vector3d::UnitY()).normalized()).normalized();
    const auto u = ls::relight::led_triangle(leds, {}, step, 0.3);
    ASSERT_TRUE(u.has_value());
    auto weight_of = [](const ls::relight::LedTriangle& tri, int led) {
      double w = 0;
      for (int k = 0; k < 3; ++k) w += tri.leds[size_t(k)] == led ? tri.weights[size_t(k)] : 0;
      return w;
    };
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(weight_of(*t, t->leds[size_t(k)]), weight_of(*u, t->leds[size_t(k)]), 0.01);
      EXPECT_NEAR(weight_of(*t, u->leds[size_t(k)]), weight_of(*u, u->leds[size_t(k)]), 0.01);
    }
    ++checked;
  }
  EXPECT_EQ(checked, 200);
  // Below the dome, farther than the coverage from any LED: no light there.
  EXPECT_FALSE(ls::relight::led_triangle(leds, {}, Eigen::Vector3d(0, -1, 0), 0.3).has_value());
}

}  // namespace
