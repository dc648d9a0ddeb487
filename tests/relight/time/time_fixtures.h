#pragma once
// Fields of a time-varying simulated scene for the temporal-fit tests: per time step, the
// simulator's noise-free one-light images of the scene's materials at that time plus the sensor's
// noise (sim/noisy_field.h) with the fit's noise model.
#include <vector>

#include "capture/field.h"
#include "lightstage/stage.h"
#include "relight/fit/normals.h"
#include "sim/noisy_field.h"
#include "sim/scene.h"
#include "sim/time_varying.h"

namespace ls::relight::time_testing {

// The true process at a hit (not varying for static materials and the background).
inline sim::ProcessTruth truth_of(const sim::Scene& scene, const sim::SurfaceHit& h) {
  if (!h.hit || h.material_index < 0) return {};
  return sim::truth_at(scene.materials[h.material_index], h.st.x(), h.st.y());
}

// One field at scene time time_s: R(x, l) ideal + noise. LEDs in `dead` are marked invalid and
// their samples zeroed, as build_field does for a dead LED.
inline capture::ReflectanceField field_at(const Stage& stage, const sim::Scene& scene,
                                          double time_s, const NoiseModel& noise, uint64_t seed,
                                          const std::vector<int>& dead = {}) {
  sim::SimFieldOptions options;
  options.scene_time_s = time_s;
  options.dead_leds = dead;
  capture::ReflectanceField field =
      sim::render_noisy_field(stage, scene, noise.as_field_noise(), seed, options);
  field.source = "sim t=" + std::to_string(time_s);
  return field;
}

}  // namespace ls::relight::time_testing
