#pragma once
// Measurement noise of a capture, estimated from the session itself, and carried into field units
// (FieldNoise: variance(v) = read_variance + shot_variance_per_unit * v).
//
// Two sensor terms, in normalised linear units (full scale = 1, after the response is inverted):
//  - read: the variance of one frame with no light, per exposure step, from pairs of dark frames.
//    The difference of two darks of the same step cancels fixed pattern (black level, hot pixels,
//    dark-current non-uniformity) and leaves twice the temporal variance (read, dark-current shot,
//    quantisation). Spread: a clipped variance (values beyond 5 MAD-sigmas dropped, for hot pixels
//    and cosmic rays), not MAD itself: the difference of quantised frames takes few distinct values
//    at low read noise, where MAD is biased by up to 50%.
//  - shot: photon transfer from the data. A sample's shot variance is K * gain * mu (mu: its
//    normalised signal above dark; K = 1 / full-well electrons for an ideal sensor). Two exposures
//    k < j of the same LED see the same scene, mu_j = r mu_k with r = (t g)_j / (t g)_k, so
//      D = (x_j - dark_j) - r (x_k - dark_k)  has mean 0 and variance
//      read_j (1 + 1/N_j) + r^2 read_k (1 + 1/N_k) + K mu_k r (g_j + r g_k)
//    (N: dark frames averaged). Binned by level, the excess of var(D) over its read part gives K.
//    Why from data rather than the stage's camera model: real back-ends state no full well; the
//    simulated sensor's parameters are used only when the bracket has no usable pair.
#include <string>
#include <vector>

#include "capture/field.h"
#include "capture/hdr_merge.h"
#include "capture/response.h"
#include "lightstage/image.h"

namespace ls::capture {

// One exposure step of the bracket, as the merge sees it.
struct NoiseStep {
  double exposure_s = 0.0;
  double gain = 1.0;
  int dark_frames = 0;      // Averaged into the step's dark (0: not dark-subtracted).
  double dark_level = 0.0;  // Mean normalised linear value of the step's dark frame.
};

// Sensor noise in normalised linear units of one frame.
struct SensorNoise {
  std::vector<double> read_variance;  // Per exposure step; meaningful where read_measured.
  bool read_measured = false;         // Every step had >= 2 dark frames.
  double shot_per_level = 0.0;        // K: shot variance per unit normalised signal at gain 1.
  bool shot_measured = false;         // From photon transfer (false: from a model or absent).
  long long dark_samples = 0;         // Differences used for read_variance.
  long long transfer_samples = 0;     // Differences used for shot_per_level.
};

// Variance of one (linearised) frame of a step, from dark frames of that step: pairs (0,1), (2,3),
// ... differenced, all channels pooled. Needs >= 2 frames (InputError otherwise). `samples` gets
// the number of differences used.
double dark_read_variance(const std::vector<const RawFrame*>& darks, const ResponseCurve& response,
                          long long* samples = nullptr);

// One photon-transfer sample: the difference D of exposure steps `short_step` < `long_step` of one
// pixel and channel (see above), at level mu of the shorter step.
struct TransferSample {
  int short_step = 0;
  int long_step = 0;
  float level = 0;  // mu_short, normalised (estimated from the longer exposure, the less noisy).
  float difference = 0;
};

// Samples from one LED's bracket: consecutive steps (by exposure * gain) that both have a dark and
// are both below the merge's saturation ramp, every `pixel_stride`-th pixel. `darks[k]` is step
// k's mean dark (linearised) or null.
std::vector<TransferSample> transfer_samples(const std::vector<const RawFrame*>& frames,
                                             const std::vector<const Image*>& darks,
                                             const ResponseCurve& response,
                                             const std::vector<NoiseStep>& steps,
                                             const MergeOptions& merge, int pixel_stride = 1);

// K from the samples, given each step's read variance: per (pair of steps, level bin) the clipped
// variance of D less its read part, over its shot coefficient; the median over bins where shot
// noise dominates and that hold >= 100 samples. False when no bin qualifies. `used` gets the
// number of samples in qualifying bins.
bool solve_shot_per_level(const std::vector<TransferSample>& samples,
                          const std::vector<NoiseStep>& steps,
                          const std::vector<double>& read_variance, double* shot_per_level,
                          long long* used = nullptr);

// How the merge combines a bracket (mirrors merge_bracket's weights) and converts to field units.
struct MergeNoiseModel {
  std::vector<NoiseStep> steps;
  MergeOptions merge;
  double radiometric_scale = 1.0;
};

// Mean squared error of one merged field value of true value v >= 0 (field units), for an LED of
// irradiance `irradiance` in that channel: the merge of the bracket simulated with each step's
// noise (fixed seed, so deterministic), because near the noise floor the merge's weights depend on
// the samples themselves and no closed form holds.
double merged_field_variance(double v, double irradiance, const SensorNoise& sensor,
                             const MergeNoiseModel& model);

// The linear FieldNoise closest to merged_field_variance: read_variance is its value at v = 0;
// shot_variance_per_unit minimises the relative error over `values` above 4 sigmas of that floor
// (a sample of the field: the line fits where the fits use data, the lit samples; the true curve
// steepens as the longer exposures saturate). `method` is copied into the result.
FieldNoise fit_field_noise(const SensorNoise& sensor, const MergeNoiseModel& model,
                           double irradiance, const std::vector<float>& values,
                           const std::string& method);

// A build's FieldNoise: the dark-frame read noise (sensor.read_measured) with the shot term from
// photon transfer over the bracket pairs (else a simulated sensor's full well, when given > 0),
// propagated through the merge at the median of the LEDs' irradiance (the field stores one model
// for all LEDs) by fit_field_noise on the field's sampled values. `sensor` gains the shot term;
// a noise that cannot be measured is the default FieldNoise, with a warning saying why.
FieldNoise estimate_build_noise(SensorNoise& sensor, const std::vector<TransferSample>& transfer,
                                const MergeNoiseModel& model, double simulated_full_well_e,
                                std::vector<double> led_irradiance,
                                const std::vector<float>& field_values,
                                std::vector<std::string>& warnings);

// The field values the noise fit samples: `count` at random positions of the field's
// layout (random rather than strided: a stride could fall in step with the 3 * lights layout),
// taken as each LED is merged, so that no pass over the whole field is needed.
class FieldValueSamples {
 public:
  FieldValueSamples(int width, int height, int num_lights, size_t count);
  // LED `light`'s values (rgb[3 * pixel + c]).
  void take(int light, const std::vector<float>& rgb);
  const std::vector<float>& values() const { return values_; }

 private:
  struct Pick {
    size_t offset, slot;  // Into an LED's rgb, into values_.
  };
  std::vector<std::vector<Pick>> by_light_;
  std::vector<float> values_;
};

}  // namespace ls::capture
