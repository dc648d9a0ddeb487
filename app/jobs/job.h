#pragma once
// What every job shares: progress reporting and the record of the options used.
#include <cmath>
#include <cstdio>
#include <string>

#include "lightstage/progress.h"

namespace ls::jobs {

// Every job reports progress by phases and times them (lightstage/progress.h).
using ls::Clock;
using ls::ProgressFn;
using ls::report;
using ls::seconds_since;

// EXR header attribute that records the options a job ran with (JSON), so every output says how
// it was made.
inline constexpr const char* kOptionsAttribute = "lightstage:options";

// A map's rotation about +Y (relight, render, play --rotate): within 100 turns, as an output's
// name carries the angle in whole degrees. Empty, or the problem naming the option.
inline std::string rotation_problem(double degrees) {
  if (std::abs(degrees) <= 36000) return {};
  char got[64];
  std::snprintf(got, sizeof got, "%g", degrees);
  return std::string("--rotate: expected angles in degrees within [-36000, 36000], got ") + got;
}

// A preview's exposure in stops: within +-64 (a factor of 2^64 is beyond any scene's range, and
// a larger one overflows the pixels). Empty, or the problem naming the option.
inline std::string exposure_problem(double stops) {
  if (std::abs(stops) <= 64) return {};
  char got[64];
  std::snprintf(got, sizeof got, "%g", stops);
  return std::string("--exposure: expected stops within [-64, 64], got ") + got;
}

}  // namespace ls::jobs
