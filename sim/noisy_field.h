#pragma once
// Simulated reflectance fields for tests, benches and evaluation: the simulator's noise-free
// one-light images (the ideal R(x, l)) plus the sensor's noise as a built field carries it.
//
// The sensor model, and why it has two levels. The simulated camera (SimStage, sim_stage.h) makes
// raw frames in electrons: Poisson shot noise, Gaussian read noise, dark current, clipping at the
// full well, quantisation and the response curve (lightstage::SimulatedSensor);
// capture::build_field then subtracts darks and merges the bracket. A field rendered here skips the
// frames and carries what that chain leaves, to first order: Gaussian noise of variance
//   read_variance + shot_variance_per_unit * max(v, 0)            (capture::FieldNoise)
// on every sample v. field_noise_of() derives those two numbers from the camera's own sensor, so
// both levels describe one sensor; tests that need a particular noise level pass it directly.
#include <cstdint>
#include <vector>

#include "capture/field.h"
#include "lightstage/stage.h"
#include "sim/scene.h"

namespace ls::sim {

// The field-level noise of one exposure of `exposure_s` at gain 1 by the stage's simulated
// camera, in the field's radiance units: with S = radiometric_scale / exposure_s the radiance that
// reads full scale and W the full well, v collects v * W / S electrons, so
//   read_variance = (S * read_noise_e / W)^2,  shot_variance_per_unit = S / W.
// Dark current and quantisation are left out (build_field subtracts the one, the other is small).
capture::FieldNoise field_noise_of(const CameraSpec& camera, double exposure_s);

struct SimFieldOptions {
  double scene_time_s = 0.0;   // Materials as they are at this scene time (sim/time_varying.h).
  std::vector<int> dead_leds;  // Marked invalid with zero samples, as build_field leaves them.
};

// The ideal field of `scene` seen by `stage`: sample (x, l) is SimStage::one_light_image(l) (near
// field for LEDs with a distance), noise-free; field.noise is left unmeasured. When `hits` is
// given it receives the camera's surface hits at options.scene_time_s (the ground truth).
capture::ReflectanceField render_ideal_field(const Stage& stage, const Scene& scene,
                                             const SimFieldOptions& options = {},
                                             std::vector<SurfaceHit>* hits = nullptr);

// The field-level sensor model: adds to every sample of every valid light Gaussian noise of
// variance noise.read_variance + noise.shot_variance_per_unit * max(v, 0), drawn from one
// std::mt19937_64(seed) light by light, then row, column and channel (so a field's noise does not
// depend on how it is tiled), and records `noise` in field.noise as measured.
void add_sensor_noise(capture::ReflectanceField& field, const capture::FieldNoise& noise,
                      uint64_t seed);

// render_ideal_field, then add_sensor_noise: the one way tests and benches get a noisy field.
capture::ReflectanceField render_noisy_field(const Stage& stage, const Scene& scene,
                                             const capture::FieldNoise& noise, uint64_t seed,
                                             const SimFieldOptions& options = {},
                                             std::vector<SurfaceHit>* hits = nullptr);

}  // namespace ls::sim
