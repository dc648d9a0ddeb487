#pragma once
// Fields for the fitting tests: the simulator's noise-free one-light images plus the sensor's
// noise (sim/noisy_field.h) with the fit's own noise model, so parameter errors can be compared
// with their truth.
#include <vector>

#include "capture/field.h"
#include "lightstage/stage.h"
#include "relight/fit/normals.h"
#include "sim/noisy_field.h"

namespace ls::relight::fit_testing {

// The ideal R(x, l) from the simulator plus Gaussian noise with the NoiseModel's variance.
struct SimField {
  capture::ReflectanceField field;
  std::vector<sim::SurfaceHit> hits;
};

inline SimField render_field(const Stage& stage, const sim::Scene& scene, const NoiseModel& noise,
                             uint64_t seed) {
  SimField out;
  out.field = sim::render_noisy_field(stage, scene, noise.as_field_noise(), seed, {}, &out.hits);
  return out;
}

}  // namespace ls::relight::fit_testing
