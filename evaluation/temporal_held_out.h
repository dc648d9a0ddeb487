#pragma once
// Temporal fits judged at the time steps they were not given: a time-lapse of the
// simulator's rise-and-fall scene (sim::rise_and_fall_scene: a corroding metal whose red rises and
// falls, a stone slab wetted and drying), some steps captured with noise, the temporal models
// fitted from those and rendered under every LED at every step, against the simulator's
// noise-free images. Beside them: the two captured neighbours' images interpolated linearly in
// time, the nearest captured step's image, each pixel's per-step BRDF fits interpolated in time,
// and at the captured steps each step's own BRDF fit.
//
// Error: relative RMS sqrt(sum (model - truth)^2 / sum truth^2) over a material's pixels and the
// LEDs that reach them (n . l > 0 and no cast shadow: a shadow is in the images and in no model,
// so what is compared is what the models model), every channel.
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/stage.h"
#include "relight/time/temporal_fit.h"
#include "sim/scene.h"

namespace ls::evaluation {

struct TimeLapse {
  Stage stage;
  sim::Scene scene;
  std::vector<sim::SurfaceHit> hits;
  std::vector<capture::ReflectanceField> noisy;  // Every step, as a capture would have them.
  std::vector<capture::ReflectanceField> ideal;  // The truth at every step.
};

// `steps` evenly spaced steps over [0, duration_s] of the rise-and-fall scene on a Fibonacci dome
// of `leds` LEDs, at the fit's default noise (relight::NoiseModel), seeded. exposure: the scene's
// radiance scale (0.2: a capture five times darker, the same sensor noise); the truth is as
// exposed.
TimeLapse rise_and_fall_time_lapse(int leds, int width, int height, int steps, double duration_s,
                                   uint64_t seed = 40, double exposure = 1.0);

struct ErrorSum {
  double err2 = 0, ref2 = 0;
  double relative() const;
};
using ErrorsByMaterial = std::map<std::string, ErrorSum>;  // Varying materials, by name.
// Every material's sums together.
ErrorSum total(const ErrorsByMaterial& errors);

struct HeldOutScores {
  // At the steps held out.
  ErrorsByMaterial fit;  // The temporal fit (default: processes, curves, held-out model choice).
  ErrorsByMaterial by_bic_alone;    // Processes and curves chosen by BIC (hold_out_steps = false).
  ErrorsByMaterial processes_only;  // The processes chosen by BIC (no curves, no held-out choice).
  ErrorsByMaterial step_fits_interpolated;  // Every pixel's per-step fits, linear in time (kSteps).
  ErrorsByMaterial linear;                  // The captured neighbours' images, linear in time.
  ErrorsByMaterial nearest;                 // The nearest captured step's image.
  // At the captured steps.
  ErrorsByMaterial fit_at_captured;
  ErrorsByMaterial step_fits_at_captured;  // Each step's own BRDF fit (fit_step, same normals).
  ErrorsByMaterial photos_at_captured;     // The captured photographs themselves (their noise).
  relight::TemporalMaps maps;              // The temporal fit.
};

// Fits the steps `captured` (indices into the time lapse, increasing, at least two, the first and
// the last step among them) with `options` and scores every other step.
HeldOutScores score_held_out(const TimeLapse& lapse, const std::vector<int>& captured,
                             const relight::TemporalFitOptions& options = {});

// `count` steps of `steps`, evenly spread, the first and the last among them.
std::vector<int> evenly_spaced_steps(int steps, int count);

// A time edit and an effect transfer on the time lapse's curve-modelled materials, as a labelled
// grid of renders under one light at `columns` times over the lapse: the fitted maps; the stone
// slab's process twice as fast (rate_scale 2); the metal sphere taking the slab's curve (transfer).
void write_time_edit_figure(const std::filesystem::path& png, const TimeLapse& lapse,
                            const relight::TemporalMaps& maps, int columns = 7);

}  // namespace ls::evaluation
