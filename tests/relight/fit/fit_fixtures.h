#pragma once
// Fields for the fitting tests: the simulator's noise-free one-light images plus Gaussian noise
// drawn from the fit's own noise model, so parameter errors can be compared with their truth.
#include <cmath>
#include <random>
#include <vector>

#include "capture/field.h"
#include "lightstage/stage.h"
#include "relight/fit/normals.h"
#include "sim/sim_stage.h"

namespace ls::relight::fit_testing {

// The ideal R(x, l) from the simulator plus Gaussian noise with the NoiseModel's variance.
struct SimField {
  capture::ReflectanceField field;
  std::vector<sim::SurfaceHit> hits;
};

inline SimField render_field(const Stage& stage, const sim::Scene& scene, const NoiseModel& noise,
                             uint64_t seed) {
  sim::SimStage sim_stage(stage, scene, seed);
  std::vector<capture::FieldLight> lights;
  for (const Led& led : stage.leds) lights.push_back({led.id, led.dir_in_stage, true});
  SimField out{capture::ReflectanceField(stage.camera.width, stage.camera.height, lights),
               sim_stage.hits()};
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss;
  for (int l = 0; l < int(stage.leds.size()); ++l) {
    const Image& image = sim_stage.one_light_image(l);
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        for (int c = 0; c < 3; ++c) {
          const double v = image.at(x, y, c);
          out.field.at(x, y, l, c) = float(v + std::sqrt(noise.variance(v)) * gauss(rng));
        }
      }
    }
  }
  return out;
}

}  // namespace ls::relight::fit_testing
