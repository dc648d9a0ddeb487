#pragma once
// Internal to the temporal fit (relight/temporal_fit*.cc): constants and helpers the per-step
// BRDF fits and the temporal curve models share. Not part of the public API.
#include <algorithm>
#include <cmath>

namespace ls::relight::temporal_internal {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kMinRoughness = 0.02;
inline constexpr double kMaxSigma = 0.5 * kPi;
// Standard deviation standing for "no information" (a parameter the step does not constrain, e.g.
// the roughness of a lobe with k_s = 0): weight 1e-12, i.e. none.
inline constexpr double kNoInformationSigma = 1e6;

template <class T>
T sigmoid(const T& u) {
  using std::exp;
  return T(1) / (T(1) + exp(-u));
}
inline double logit(double p) {
  p = std::clamp(p, 1e-4, 1 - 1e-4);
  return std::log(p / (1 - p));
}

}  // namespace ls::relight::temporal_internal
