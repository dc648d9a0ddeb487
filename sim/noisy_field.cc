#include "sim/noisy_field.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "lightstage/errors.h"
#include "sim/sim_stage.h"

namespace ls::sim {

capture::FieldNoise field_noise_of(const CameraSpec& camera, double exposure_s) {
  LS_CHECK(exposure_s > 0 && camera.simulated.full_well_e > 0,
           "field_noise_of: exposure " + std::to_string(exposure_s) + " s, full well " +
               std::to_string(camera.simulated.full_well_e) + " e-");
  const double full_scale = camera.radiometric_scale / exposure_s;
  const double per_electron = full_scale / camera.simulated.full_well_e;
  capture::FieldNoise noise;
  noise.read_variance = std::pow(per_electron * camera.simulated.read_noise_e, 2);
  noise.shot_variance_per_unit = per_electron;
  noise.method = "simulated sensor";
  return noise;
}

capture::ReflectanceField render_ideal_field(const Stage& stage, const Scene& scene,
                                             const SimFieldOptions& options,
                                             std::vector<SurfaceHit>* hits) {
  SimStage sim_stage(stage, scene, /*seed=*/1);  // The seed is the camera's; no frames are taken.
  sim_stage.set_scene_time(options.scene_time_s);
  std::vector<capture::FieldLight> lights;
  for (const Led& led : stage.leds) lights.push_back({led.id, led.dir_in_stage, true});
  for (const int l : options.dead_leds) {
    LS_CHECK(l >= 0 && l < int(lights.size()), "dead LED index " + std::to_string(l));
    lights[l].valid = false;
  }
  capture::ReflectanceField field(stage.camera.width, stage.camera.height, lights);
  field.scene_time_s = options.scene_time_s;
  field.source = scene.source.empty() ? "sim" : scene.source;
  for (int l = 0; l < int(lights.size()); ++l) {
    if (!lights[l].valid) continue;
    const Image& image = sim_stage.one_light_image(l);
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        for (int c = 0; c < 3; ++c) field.at(x, y, l, c) = image.at(x, y, c);
      }
    }
  }
  if (hits) *hits = sim_stage.hits();
  return field;
}

void add_sensor_noise(capture::ReflectanceField& field, const capture::FieldNoise& noise,
                      uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss;
  for (int l = 0; l < field.num_lights(); ++l) {
    if (!field.lights()[l].valid) continue;
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        for (int c = 0; c < 3; ++c) {
          float& v = field.at(x, y, l, c);
          const double variance =
              noise.read_variance + noise.shot_variance_per_unit * std::max(double(v), 0.0);
          v = float(v + std::sqrt(variance) * gauss(rng));
        }
      }
    }
  }
  field.noise = noise;
  field.noise.measured = true;
  if (field.noise.method.empty()) field.noise.method = "simulated";
}

capture::ReflectanceField render_noisy_field(const Stage& stage, const Scene& scene,
                                             const capture::FieldNoise& noise, uint64_t seed,
                                             const SimFieldOptions& options,
                                             std::vector<SurfaceHit>* hits) {
  capture::ReflectanceField field = render_ideal_field(stage, scene, options, hits);
  add_sensor_noise(field, noise, seed);
  return field;
}

}  // namespace ls::sim
