#include "sim/envmaps.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <string>

#include "lightstage/angles.h"
#include "lightstage/errors.h"
#include "physics/envmap.h"

namespace ls::sim {

namespace {

Eigen::Vector3d from_elevation_azimuth(double elevation_deg, double x_weight, double z_weight) {
  const Eigen::Vector2d horizontal = Eigen::Vector2d(x_weight, z_weight).normalized();
  const double el = elevation_deg * kDegToRad;
  return Eigen::Vector3d(std::cos(el) * horizontal.x(), std::sin(el),
                         std::cos(el) * horizontal.y());
}

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

using RadianceFn = std::function<Eigen::Vector3d(const Eigen::Vector3d&)>;

// Fills a map with `smooth` at pixel centres plus the pixel average of `compact`, a source
// confined within `compact_radius_rad` of `compact_dir`: pixels near it are supersampled
// (16x16, solid-angle weighted) so the source's power is kept however small it is.
Image render_map(int width, const RadianceFn& smooth, const RadianceFn& compact,
                 const Eigen::Vector3d& compact_dir, double compact_radius_rad) {
  LS_CHECK(width >= 8 && width % 2 == 0,
           "map width must be even and >= 8, got " + std::to_string(width));
  const int height = width / 2;
  Image map(width, height, 3);
  map.channel_names = {"R", "G", "B"};
  // A pixel's half diagonal in angle is at most about pi / height.
  const double near_cos = std::cos(compact_radius_rad + 1.5 * std::numbers::pi / height);
  constexpr int kSub = 16;
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        const Eigen::Vector3d d =
            physics::EnvironmentMap::direction((x + 0.5) / width, (y + 0.5) / height);
        Eigen::Vector3d value = smooth(d);
        if (compact && d.dot(compact_dir) > near_cos) {
          Eigen::Vector3d sum(0, 0, 0);
          double weight = 0;
          for (int sy = 0; sy < kSub; ++sy) {
            const double v = (y + (sy + 0.5) / kSub) / height;
            const double w_solid = std::sin(std::numbers::pi * v);
            for (int sx = 0; sx < kSub; ++sx) {
              sum += w_solid * compact(physics::EnvironmentMap::direction(
                                   (x + (sx + 0.5) / kSub) / width, v));
              weight += w_solid;
            }
          }
          if (weight > 0) value += sum / weight;
        }
        for (int c = 0; c < 3; ++c) map.at(x, y, c) = float(value[c]);
      }
    }
  });
  return map;
}

// Sky radiance: blue overhead, pale at the horizon, a dim ground below; brighter around the sun.
Eigen::Vector3d sky_radiance(const Eigen::Vector3d& d, const Eigen::Vector3d& sun) {
  const Eigen::Vector3d zenith(0.06, 0.12, 0.30), horizon(0.26, 0.28, 0.30),
      ground(0.05, 0.045, 0.04);
  Eigen::Vector3d sky;
  if (d.y() >= 0) {
    sky = horizon + (zenith - horizon) * std::sqrt(d.y());
  } else {
    // Half a degree of blend so the horizon is not a hard step.
    sky = ground + (horizon - ground) * (1 - smoothstep(0, std::sin(0.5 * kDegToRad), -d.y()));
  }
  const double angle_to_sun = std::acos(std::clamp(d.dot(sun), -1.0, 1.0));
  const double aureole = 1.5 * std::exp(-angle_to_sun / (8 * kDegToRad));
  return sky * (1 + (d.y() >= 0 ? aureole : 0));
}

}  // namespace

Eigen::Vector3d sky_sun_direction() { return from_elevation_azimuth(35, -0.64, 0.77); }

Eigen::Vector3d small_source_direction() {
  return from_elevation_azimuth(50, std::cos(30 * kDegToRad), std::sin(30 * kDegToRad));
}

double small_source_radiance() {
  // Irradiance at normal incidence of a uniform disc of angular radius r: L * pi * sin^2(r).
  const double s = std::sin(kSmallSourceRadiusDeg * kDegToRad);
  return 1.0 / (std::numbers::pi * s * s);
}

Image make_sky_with_sun(int width) {
  const Eigen::Vector3d sun = sky_sun_direction();
  const double radius = kSunRadiusDeg * kDegToRad;
  // About 1e4 x the sky's radiance: a surface facing the sun gets about as much irradiance from
  // the 0.5 deg disc as from the whole sky, so it casts crisp, clearly visible shadows.
  const Eigen::Vector3d sun_radiance = 2500.0 * Eigen::Vector3d(1.0, 0.93, 0.82);
  auto smooth = [&](const Eigen::Vector3d& d) { return sky_radiance(d, sun); };
  auto disc = [&](const Eigen::Vector3d& d) -> Eigen::Vector3d {
    const double angle = std::acos(std::clamp(d.dot(sun), -1.0, 1.0));
    if (angle >= radius) return Eigen::Vector3d::Zero();
    // Limb darkening I(mu) = 1 - 0.6 (1 - mu), mu the cosine across the disc.
    const double r = angle / radius;
    const double mu = std::sqrt(1 - r * r);
    return sun_radiance * (1 - 0.6 * (1 - mu));
  };
  return render_map(width, smooth, disc, sun, radius);
}

Image make_studio(int width) {
  struct AreaLight {
    Eigen::Vector3d center;
    double half_width_rad, half_height_rad;  // Angular half extents across and up.
    Eigen::Vector3d radiance;
  };
  const AreaLight lights[] = {
      // Key: front-left, high, warm.
      {from_elevation_azimuth(30, -0.7, 0.7), 20 * kDegToRad, 15 * kDegToRad, {4.0, 3.7, 3.3}},
      // Fill: front-right, low, cool and dimmer.
      {from_elevation_azimuth(10, 0.8, 0.6), 25 * kDegToRad, 18 * kDegToRad, {0.7, 0.8, 1.0}},
      // Rim: behind, high, a narrow tall strip.
      {from_elevation_azimuth(45, 0.3, -0.95), 7 * kDegToRad, 25 * kDegToRad, {5.0, 5.0, 5.0}},
  };
  const double soft_edge_rad = 3 * kDegToRad;
  auto smooth = [&](const Eigen::Vector3d& d) {
    Eigen::Vector3d value(0.004, 0.004, 0.005);  // The dark studio itself.
    for (const AreaLight& l : lights) {
      const double forward = d.dot(l.center);
      if (forward <= 0) continue;
      const Eigen::Vector3d right = Eigen::Vector3d::UnitY().cross(l.center).normalized();
      const Eigen::Vector3d up = l.center.cross(right);
      const double a = std::abs(std::atan2(d.dot(right), forward));
      const double b = std::abs(std::atan2(d.dot(up), forward));
      const double mask = (1 - smoothstep(l.half_width_rad - soft_edge_rad, l.half_width_rad, a)) *
                          (1 - smoothstep(l.half_height_rad - soft_edge_rad, l.half_height_rad, b));
      value += mask * l.radiance;
    }
    return value;
  };
  return render_map(width, smooth, nullptr, Eigen::Vector3d::UnitY(), 0.0);
}

Image make_small_source(int width) {
  const Eigen::Vector3d dir = small_source_direction();
  const double radius = kSmallSourceRadiusDeg * kDegToRad;
  const double cos_radius = std::cos(radius);
  const double radiance = small_source_radiance();
  auto none = [](const Eigen::Vector3d&) { return Eigen::Vector3d::Zero().eval(); };
  auto disc = [&](const Eigen::Vector3d& d) -> Eigen::Vector3d {
    return d.dot(dir) >= cos_radius ? Eigen::Vector3d::Constant(radiance) : Eigen::Vector3d::Zero();
  };
  return render_map(width, none, disc, dir, radius);
}

}  // namespace ls::sim
