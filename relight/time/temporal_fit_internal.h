#pragma once
// Internal to the temporal fit (relight/temporal_fit*.cc): constants the per-step BRDF fits and the
// temporal curve models share. Not part of the public API. The solver core, samples and bounded
// parametrisations are relight/fit/pixel_solver.h, shared with the static fit.
#include "relight/fit/pixel_solver.h"

namespace ls::relight::temporal_internal {

using pixel::kMinRoughness;
using pixel::kPi;
inline constexpr double kMaxSigma = 0.5 * kPi;
// Standard deviation standing for "no information" (a parameter the step does not constrain, e.g.
// the roughness of a lobe with k_s = 0): weight 1e-12, i.e. none.
inline constexpr double kNoInformationSigma = 1e6;

}  // namespace ls::relight::temporal_internal
