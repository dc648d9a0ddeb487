#include "relight/sources/bright_sources.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <utility>

#include "lightstage/angles.h"
#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"

namespace ls::relight {

namespace {

// The 8-connected pixels of a lat-long map at or above a luminance, grown from a seed (wrapping
// in u), and whether all of them lie within max_angle of the seed's direction.
struct Region {
  std::vector<int> pixels;  // y * width + x.
  bool compact = true;
};

Region grow_region(const physics::EnvironmentMap& map, const std::vector<double>& lum,
                   double threshold, int seed, double max_angle) {
  const int width = map.width(), height = map.height();
  const Eigen::Vector3d seed_dir = map.pixel_direction(seed % width, seed / width);
  Region region;
  std::vector<int> stack{seed};
  std::vector<char> visited(lum.size(), 0);
  visited[size_t(seed)] = 1;
  while (!stack.empty()) {
    const int p = stack.back();
    stack.pop_back();
    region.pixels.push_back(p);
    const int x = p % width, y = p / width;
    if (angle_between(seed_dir, map.pixel_direction(x, y)) > max_angle) region.compact = false;
    for (int dy = -1; dy <= 1; ++dy) {
      const int ny = y + dy;
      if (ny < 0 || ny >= height) continue;
      for (int dx = -1; dx <= 1; ++dx) {
        const int q = ny * width + (x + dx + width) % width;
        if (visited[size_t(q)] || lum[size_t(q)] < threshold) continue;
        visited[size_t(q)] = 1;
        stack.push_back(q);
      }
    }
  }
  return region;
}

// The compact core of the bright region around a seed: grown at the threshold, then at doubling
// thresholds while it is too wide (a sun inside its glow, or in a sunrise's bright haze).
Region compact_core(const physics::EnvironmentMap& map, const std::vector<double>& lum,
                    double threshold, int seed, double max_angle, std::vector<char>& visited) {
  Region region = grow_region(map, lum, threshold, seed, max_angle);
  for (const int p : region.pixels) visited[size_t(p)] = 1;  // The glow seeds nothing more.
  for (double t = 2 * threshold; !region.compact && t <= lum[size_t(seed)]; t *= 2) {
    region = grow_region(map, lum, t, seed, max_angle);
  }
  return region;
}

// Solid-angle weighted mean radiance of the pixels within `ring` pixels of the region, outside it.
Eigen::Vector3d border_radiance(const physics::EnvironmentMap& map, const std::vector<int>& region,
                                int ring) {
  const int width = map.width(), height = map.height();
  std::vector<char> inside(size_t(width) * height, 0), counted(size_t(width) * height, 0);
  for (int p : region) inside[size_t(p)] = 1;
  Eigen::Vector3d sum(0, 0, 0);
  double weight = 0;
  for (int p : region) {
    const int x = p % width, y = p / width;
    for (int dy = -ring; dy <= ring; ++dy) {
      const int ny = y + dy;
      if (ny < 0 || ny >= height) continue;
      for (int dx = -ring; dx <= ring; ++dx) {
        const size_t q = size_t(ny) * width + size_t((x + dx + width) % width);
        if (inside[q] || counted[q]) continue;
        counted[q] = 1;
        const double w = map.pixel_solid_angle_sr(ny);
        const float* l = &map.radiance().pixels[3 * q];
        sum += w * Eigen::Vector3d(l[0], l[1], l[2]);
        weight += w;
      }
    }
  }
  return weight > 0 ? Eigen::Vector3d(sum / weight) : Eigen::Vector3d::Zero();
}

}  // namespace

std::string BrightSource::describe() const {
  const Eigen::Vector3d& d = dir;
  const double elevation = std::asin(std::clamp(d.y(), -1.0, 1.0)) / kDegToRad;
  // Azimuth in the stage frame: 0 toward the camera (+Z), 90 toward +X.
  const double azimuth = std::atan2(d.x(), d.z()) / kDegToRad;
  char line[160];
  std::snprintf(line, sizeof line,
                "bright source at elevation %.1f deg, azimuth %.1f deg, radius %.2f deg, %.1f%% "
                "of the map's light",
                elevation, azimuth, radius_rad / kDegToRad, 100.0 * energy_share);
  return line;
}

std::string BrightSourceOptions::validate() const {
  if (!(std::isfinite(min_contrast) && min_contrast > 1)) return "min_contrast: expected > 1";
  if (!(max_radius_deg > 0 && max_radius_deg <= 45)) return "max_radius_deg: expected (0, 45]";
  if (!(min_energy_share >= 0 && min_energy_share <= 1)) return "min_energy_share: expected [0, 1]";
  if (max_sources < 0) return "max_sources: expected >= 0";
  return {};
}

SplitEnvironment split_bright_sources(const physics::EnvironmentMap& map,
                                      const BrightSourceOptions& options) {
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError("bright sources: " + error);
  }
  const int width = map.width(), height = map.height();
  const std::vector<float>& radiance = map.radiance().pixels;
  std::vector<double> lum(size_t(width) * height);
  double total = 0;  // Luminance integral over the sphere.
  for (int y = 0; y < height; ++y) {
    const double sr = map.pixel_solid_angle_sr(y);
    for (int x = 0; x < width; ++x) {
      const size_t p = size_t(y) * width + x;
      lum[p] = ls::luminance(radiance[3 * p], radiance[3 * p + 1], radiance[3 * p + 2]);
      total += sr * lum[p];
    }
  }
  Image rest = map.radiance();
  std::vector<BrightSource> sources;
  const double threshold = options.min_contrast * total / (4 * std::numbers::pi);
  std::vector<char> visited(lum.size(), 0);
  // Seeds in decreasing luminance: each region is grown once from its brightest pixel.
  std::vector<int> order;
  for (size_t p = 0; p < lum.size(); ++p) {
    if (lum[p] >= threshold && threshold > 0) order.push_back(int(p));
  }
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return lum[size_t(a)] > lum[size_t(b)]; });
  for (const int seed : order) {
    if (int(sources.size()) >= options.max_sources) break;
    if (visited[size_t(seed)]) continue;
    const Region region =
        compact_core(map, lum, threshold, seed, 2 * options.max_radius_deg * kDegToRad, visited);
    if (!region.compact) continue;
    const Eigen::Vector3d background = border_radiance(map, region.pixels, 2);
    BrightSource source;
    Eigen::Vector3d centroid(0, 0, 0);
    std::vector<std::pair<Eigen::Vector3d, double>> weighted;  // Direction, luminance x sr.
    for (const int p : region.pixels) {
      const int x = p % width, y = p / width;
      const double sr = map.pixel_solid_angle_sr(y);
      const float* l = &radiance[3 * size_t(p)];
      Eigen::Vector3d excess;
      for (int c = 0; c < 3; ++c) excess[c] = std::max(0.0, double(l[c]) - background[c]);
      source.irradiance_rgb += sr * excess;
      const Eigen::Vector3d dir = map.pixel_direction(x, y);
      weighted.emplace_back(dir, sr * ls::luminance(excess));
      centroid += weighted.back().second * dir;
    }
    const double source_lum = ls::luminance(source.irradiance_rgb);
    if (!(source_lum > 0) || centroid.norm() == 0) continue;
    source.dir = centroid.normalized();
    source.energy_share = source_lum / total;
    // A uniform disc of radius r has mean squared angle r^2 / 2 about its centre.
    double second_moment = 0;
    for (const auto& [dir, w] : weighted)
      second_moment += w * std::pow(angle_between(dir, source.dir), 2);
    source.radius_rad = std::sqrt(2 * second_moment / source_lum);
    if (source.radius_rad > options.max_radius_deg * kDegToRad ||
        source.energy_share < options.min_energy_share) {
      continue;
    }
    for (const int p : region.pixels) {
      float* l = &rest.pixels[3 * size_t(p)];
      for (int c = 0; c < 3; ++c) l[c] = std::min(l[c], float(background[c]));
    }
    sources.push_back(source);
  }
  return {physics::EnvironmentMap(std::move(rest), map.source() + " without its bright sources"),
          std::move(sources)};
}

}  // namespace ls::relight
