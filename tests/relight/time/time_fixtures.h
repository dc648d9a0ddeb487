#pragma once
// Fields of a time-varying simulated scene for the temporal-fit tests: per time step, the
// simulator's noise-free one-light images of the scene's materials at that time (each hit's
// material replaced by sim::material_at) plus Gaussian noise from the fit's noise model.
#include <cmath>
#include <random>
#include <vector>

#include "capture/field.h"
#include "lightstage/stage.h"
#include "relight/fit/normals.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
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
                                          const std::vector<sim::SurfaceHit>& hits, double time_s,
                                          const NoiseModel& noise, uint64_t seed,
                                          const std::vector<int>& dead = {}) {
  const std::vector<sim::SurfaceHit> timed = sim::at_time(scene, hits, time_s);
  std::vector<capture::FieldLight> lights;
  for (const Led& led : stage.leds) lights.push_back({led.id, led.dir_in_stage, true});
  for (const int l : dead) lights[l].valid = false;
  capture::ReflectanceField field(stage.camera.width, stage.camera.height, lights);
  field.scene_time_s = time_s;
  field.source = "sim t=" + std::to_string(time_s);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss;
  for (int l = 0; l < int(stage.leds.size()); ++l) {
    if (!lights[l].valid) continue;
    const Image image = sim::render_one_light(scene, timed, stage.leds[l].dir_in_stage);
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        for (int c = 0; c < 3; ++c) {
          const double v = image.at(x, y, c);
          field.at(x, y, l, c) = float(v + std::sqrt(noise.variance(v)) * gauss(rng));
        }
      }
    }
  }
  return field;
}

}  // namespace ls::relight::time_testing
