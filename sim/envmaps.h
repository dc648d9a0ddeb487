#pragma once
// Procedural lat-long radiance maps for the demo and tests (the physical world's skies and
// studios). 3 channels, width x width/2, DESIGN.md's lat-long convention (row 0 is the zenith, the
// centre -Z). Small bright features (sun, small source) are supersampled so each pixel holds its
// average radiance: the maps' integrals match the analytic sources.
#include <Eigen/Core>

#include "lightstage/image.h"

namespace ls::sim {

// A blue sky gradient with a warm sun disc (0.5 deg radius) at 35 deg elevation.
Image make_sky_with_sun(int width = 512);
// A dark studio with three soft rectangular area lights (key, fill, rim).
Image make_studio(int width = 512);
// Black except one small source (2 deg radius) at 50 deg elevation to the camera's right.
Image make_small_source(int width = 512);

// Unit direction (stage frame) toward the centre of the sun of make_sky_with_sun: 35 deg
// elevation, front-left as the camera sees it.
Eigen::Vector3d sky_sun_direction();
// Unit direction toward the centre of make_small_source's disc: 50 deg elevation, to the camera's
// right (+X) and 30 deg toward the camera.
Eigen::Vector3d small_source_direction();
// Constant radiance of the small source disc: it gives irradiance 1 (per channel) at normal
// incidence.
double small_source_radiance();
inline constexpr double kSmallSourceRadiusDeg = 2.0;
inline constexpr double kSunRadiusDeg = 0.5;

}  // namespace ls::sim
