#include "capture/noise_estimate.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <string>

#include "lightstage/errors.h"

namespace ls::capture {
namespace {

// These two mirror hdr_merge.cc (kSaturationRamp, kFloorWeight): the propagation must weight the
// steps exactly as the merge does.
constexpr double kMergeSaturationRamp = 0.2;
constexpr double kMergeFloorWeight = 1e-3;

// MAD of a Gaussian is 0.6745 sigma.
constexpr double kMadToSigma = 1.4826;
// The mean absolute deviation of a Gaussian is sqrt(2 / pi) sigma.
constexpr double kSqrtPiOver2 = 1.2533141373155;
// Differences further than this many robust sigmas from the median are outliers (hot pixels,
// cosmic rays, a pixel on an edge that moved): a Gaussian loses 6e-7 of its mass here.
constexpr double kClipSigmas = 5.0;

// Photon-transfer bins: log-spaced in level, kBinsPerDecade per decade from kMinLevel to 1.
constexpr double kMinLevel = 1e-4;
constexpr int kBinsPerDecade = 4;
constexpr int kNumBins = 4 * kBinsPerDecade;
constexpr size_t kMinBinSamples = 100;

// Simulated merges per level in merged_field_variance: the variance to about 2%.
constexpr int kMergeDraws = 4000;
constexpr uint64_t kMergeDrawSeed = 0x6e6f697365ull;
// Levels at which fit_field_noise evaluates the merged variance, log-spaced over the field's range.
constexpr int kFitLevels = 40;
// NormalOptions::shadow_sigmas' default: below this many sigmas of the floor a sample is "unlit".
constexpr double kLitSigmas = 4.0;

// Variance of `values` (about their mean) after dropping those more than kClipSigmas robust sigmas
// (from the MAD, or the mean absolute deviation when more than half are identical) from the median.
double clipped_variance(std::vector<double> values) {
  if (values.size() < 2) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  const double median = values[mid];
  std::vector<double> deviation(values.size());
  for (size_t i = 0; i < values.size(); ++i) deviation[i] = std::abs(values[i] - median);
  std::nth_element(deviation.begin(), deviation.begin() + mid, deviation.end());
  double sigma = kMadToSigma * deviation[mid];
  if (!(sigma > 0)) {
    // Quantised data with little noise: MAD is 0 when more than half the values are equal.
    sigma = std::accumulate(deviation.begin(), deviation.end(), 0.0) / double(deviation.size()) *
            kSqrtPiOver2;
  }
  if (!(sigma > 0)) return 0.0;
  const double limit = kClipSigmas * sigma;
  double sum = 0, sum2 = 0;
  long long n = 0;
  for (const double v : values) {
    if (std::abs(v - median) > limit) continue;
    sum += v;
    sum2 += v * v;
    ++n;
  }
  if (n < 2) return 0.0;
  const double mean = sum / double(n);
  return std::max(0.0, (sum2 - double(n) * mean * mean) / double(n - 1));
}

}  // namespace

double dark_read_variance(const std::vector<const RawFrame*>& darks, const ResponseCurve& response,
                          long long* samples) {
  if (darks.size() < 2) {
    throw InputError("dark read noise: needs at least 2 dark frames of one exposure step, got " +
                     std::to_string(darks.size()));
  }
  const RawFrame& first = *darks[0];
  const int max_dn = (1 << response.bit_depth()) - 1;
  const std::vector<float>& lut = response.lut();
  const size_t lut_stride = response.channels() == 1 ? 0 : size_t(max_dn) + 1;
  std::vector<double> differences;
  for (size_t p = 0; p + 1 < darks.size(); p += 2) {
    const RawFrame& a = *darks[p];
    const RawFrame& b = *darks[p + 1];
    if (a.pixels.size() != first.pixels.size() || b.pixels.size() != first.pixels.size()) {
      throw InputError("dark read noise: dark frames differ in size");
    }
    for (size_t i = 0; i < a.pixels.size(); ++i) {
      const size_t c = i % size_t(first.channels);
      differences.push_back(double(lut[lut_stride * c + std::min<int>(a.pixels[i], max_dn)]) -
                            double(lut[lut_stride * c + std::min<int>(b.pixels[i], max_dn)]));
    }
  }
  if (samples) *samples = (long long)differences.size();
  // var(a - b) = 2 var(one frame).
  return clipped_variance(std::move(differences)) / 2.0;
}

std::vector<TransferSample> transfer_samples(const std::vector<const RawFrame*>& frames,
                                             const std::vector<const Image*>& darks,
                                             const ResponseCurve& response,
                                             const std::vector<NoiseStep>& steps,
                                             const MergeOptions& merge, int pixel_stride) {
  const size_t num_steps = steps.size();
  if (frames.size() != num_steps || darks.size() != num_steps) {
    throw InputError("photon transfer: expected one frame and one dark per exposure step");
  }
  std::vector<int> order(num_steps);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return steps[a].exposure_s * steps[a].gain < steps[b].exposure_s * steps[b].gain;
  });
  const int max_dn = (1 << response.bit_depth()) - 1;
  const std::vector<float>& lut = response.lut();
  const size_t lut_stride = response.channels() == 1 ? 0 : size_t(max_dn) + 1;
  // Below the merge's saturation ramp: the sample is linear and unclipped.
  const double ramp_start = merge.saturation_level * (1.0 - kMergeSaturationRamp);
  const size_t stride = size_t(std::max(1, pixel_stride));
  std::vector<TransferSample> out;
  for (size_t i = 0; i + 1 < num_steps; ++i) {
    const int k = order[i], j = order[i + 1];
    if (!frames[k] || !frames[j] || !darks[k] || !darks[j]) continue;
    const RawFrame& fk = *frames[k];
    const RawFrame& fj = *frames[j];
    const double r = steps[j].exposure_s * steps[j].gain / (steps[k].exposure_s * steps[k].gain);
    if (!(r > 1.0)) continue;  // Equal exposures are repeats, not a transfer pair.
    const int channels = fk.channels;
    const size_t pixels = size_t(fk.width) * fk.height;
    if (fj.pixels.size() != fk.pixels.size() || darks[k]->pixels.size() != fk.pixels.size() ||
        darks[j]->pixels.size() != fk.pixels.size()) {
      throw InputError("photon transfer: frames and darks differ in size");
    }
    for (size_t p = 0; p < pixels; p += stride) {
      for (int c = 0; c < channels; ++c) {
        const size_t at = p * channels + c;
        const int dn_k = std::min<int>(fk.pixels[at], max_dn);
        const int dn_j = std::min<int>(fj.pixels[at], max_dn);
        if (dn_j >= max_dn) continue;
        const double x_k = lut[lut_stride * c + dn_k];
        const double x_j = lut[lut_stride * c + dn_j];
        if (x_j >= ramp_start) continue;
        const double mu_j = x_j - darks[j]->pixels[at];
        const double mu_k = x_k - darks[k]->pixels[at];
        const double level = mu_j / r;
        if (!(level > kMinLevel)) continue;
        out.push_back({k, j, float(level), float(mu_j - r * mu_k)});
      }
    }
  }
  return out;
}

bool solve_shot_per_level(const std::vector<TransferSample>& samples,
                          const std::vector<NoiseStep>& steps,
                          const std::vector<double>& read_variance, double* shot_per_level,
                          long long* used) {
  struct Bin {
    std::vector<double> differences;
    double level_sum = 0;
  };
  std::map<std::pair<int, int>, std::vector<Bin>> bins;
  for (const TransferSample& s : samples) {
    const int bin = int(std::floor(std::log10(double(s.level) / kMinLevel) * kBinsPerDecade));
    if (bin < 0 || bin >= kNumBins) continue;
    auto& pair_bins = bins[{s.short_step, s.long_step}];
    if (pair_bins.empty()) pair_bins.resize(kNumBins);
    pair_bins[bin].differences.push_back(s.difference);
    pair_bins[bin].level_sum += s.level;
  }
  auto dark_part = [&](int step) {
    const double read = step < int(read_variance.size()) ? read_variance[step] : 0.0;
    const int n = steps[step].dark_frames;
    return read * (1.0 + (n > 0 ? 1.0 / n : 0.0));
  };
  std::vector<double> estimates;
  long long count = 0;
  for (const auto& [pair, pair_bins] : bins) {
    const auto [k, j] = pair;
    const double r = steps[j].exposure_s * steps[j].gain / (steps[k].exposure_s * steps[k].gain);
    const double read_part = dark_part(j) + r * r * dark_part(k);
    for (const Bin& bin : pair_bins) {
      if (bin.differences.size() < kMinBinSamples) continue;
      const double level = bin.level_sum / double(bin.differences.size());
      const double shot = clipped_variance(bin.differences) - read_part;
      // Where read noise dominates, the subtraction leaves mostly the read estimate's error.
      if (!(shot > read_part)) continue;
      const double coefficient = level * r * (steps[j].gain + r * steps[k].gain);
      estimates.push_back(shot / coefficient);
      count += (long long)bin.differences.size();
    }
  }
  if (used) *used = count;
  if (estimates.empty()) return false;
  const size_t mid = estimates.size() / 2;
  std::nth_element(estimates.begin(), estimates.begin() + mid, estimates.end());
  *shot_per_level = estimates[mid];
  return true;
}

double merged_field_variance(double v, double irradiance, const SensorNoise& sensor,
                             const MergeNoiseModel& model) {
  // One step k with exposure t and gain g sees, at true value v, the normalised level
  //   mu_k = v E t g / radiometric_scale above dark, with variance read_k + K g mu_k,
  // less its mean dark (variance read_k / N_k); the merge's signal is s_k = (x_k - dark_k) / (t g)
  // and the field value is s * radiometric_scale / E. Where every step is well above the floor the
  // merge is a fixed weighted mean and var(s) = sum w_k^2 var(s_k) / (sum w_k)^2 (w_k: its hat
  // weight times t g); but near the floor the weights depend on the noisy samples themselves (the
  // floor ramp weights a sample by its own value), which raises the variance near v = 0 by over an
  // order of magnitude, and biases the value. So the merge is simulated here, draw by draw, and
  // the mean squared error about v is returned: what a fit's chi^2 sees.
  const double scale = model.radiometric_scale / irradiance;
  const double saturation = model.merge.saturation_level;
  const double ramp = saturation * kMergeSaturationRamp;
  const double floor_level = model.merge.floor_level;
  const size_t num_steps = model.steps.size();
  std::vector<double> tg(num_steps), mu(num_steps), sample_sigma(num_steps), dark_sigma(num_steps);
  size_t shortest = 0;
  for (size_t k = 0; k < num_steps; ++k) {
    const NoiseStep& step = model.steps[k];
    tg[k] = step.exposure_s * step.gain;
    mu[k] = std::max(0.0, v) * tg[k] / scale;
    const double read = k < sensor.read_variance.size() ? sensor.read_variance[k] : 0.0;
    sample_sigma[k] = std::sqrt(read + sensor.shot_per_level * step.gain * mu[k]);
    dark_sigma[k] = step.dark_frames > 0 ? std::sqrt(read / step.dark_frames) : 0.0;
    if (tg[k] < tg[shortest]) shortest = k;
  }
  std::mt19937_64 rng(kMergeDrawSeed);
  std::normal_distribution<double> gauss;
  const double truth = std::max(0.0, v) / scale;  // In merged-signal units.
  double squared_error = 0;
  for (int draw = 0; draw < kMergeDraws; ++draw) {
    double weighted = 0, weight_sum = 0, shortest_signal = 0;
    for (size_t k = 0; k < num_steps; ++k) {
      const double linear = model.steps[k].dark_level + mu[k] + sample_sigma[k] * gauss(rng);
      const double above_dark = linear - model.steps[k].dark_level - dark_sigma[k] * gauss(rng);
      const double signal = above_dark / tg[k];
      if (k == shortest) shortest_signal = signal;
      if (linear >= saturation) continue;
      const double w_high = std::min(1.0, (saturation - linear) / ramp);
      const double w_low =
          floor_level > 0 ? std::clamp(above_dark / floor_level, kMergeFloorWeight, 1.0) : 1.0;
      const double w = std::min(w_high, w_low) * tg[k];
      weighted += w * signal;
      weight_sum += w;
    }
    const double merged = weight_sum > 0 ? weighted / weight_sum : shortest_signal;
    squared_error += (merged - truth) * (merged - truth);
  }
  return squared_error / kMergeDraws * scale * scale;
}

FieldNoise fit_field_noise(const SensorNoise& sensor, const MergeNoiseModel& model,
                           double irradiance, const std::vector<float>& values,
                           const std::string& method) {
  FieldNoise noise;
  noise.read_variance = merged_field_variance(0.0, irradiance, sensor, model);
  noise.measured = true;
  noise.method = method;
  // Histogram of the positive values on a log grid, then least squares in relative terms over it:
  // minimise sum n_i ((a + b v_i - V(v_i)) / V(v_i))^2 over b.
  // Only values the fits treat as lit count: they drop samples below kLitSigmas noise sigmas at
  // black, and near black the merge's variance is not linear in v (see merged_field_variance).
  const float lit = float(kLitSigmas * std::sqrt(noise.read_variance));
  float low = INFINITY, high = 0;
  for (const float value : values) {
    if (!(value > lit) || !std::isfinite(value)) continue;
    low = std::min(low, value);
    high = std::max(high, value);
  }
  if (!(high > low)) return noise;
  const double step = std::log(double(high) / low) / kFitLevels + 1e-12;
  std::vector<long long> count(kFitLevels, 0);
  for (const float value : values) {
    if (!(value >= low) || !std::isfinite(value)) continue;
    count[std::min(kFitLevels - 1, int(std::log(double(value) / low) / step))]++;
  }
  double numerator = 0, denominator = 0;
  for (int i = 0; i < kFitLevels; ++i) {
    if (count[i] == 0) continue;
    const double v = low * std::exp((i + 0.5) * step);
    const double target = merged_field_variance(v, irradiance, sensor, model);
    if (!(target > 0)) continue;
    numerator += double(count[i]) * (target - noise.read_variance) * v / (target * target);
    denominator += double(count[i]) * v * v / (target * target);
  }
  noise.shot_variance_per_unit = denominator > 0 ? std::max(0.0, numerator / denominator) : 0.0;
  return noise;
}

FieldValueSamples::FieldValueSamples(int width, int height, int num_lights, size_t count)
    : by_light_(size_t(num_lights)) {
  const size_t per_pixel = 3 * size_t(num_lights);
  const size_t total = size_t(width) * size_t(height) * per_pixel;
  std::mt19937_64 rng(1);
  std::uniform_int_distribution<size_t> pick(0, total == 0 ? 0 : total - 1);
  values_.assign(std::min(total, count), 0.0f);  // 0: an LED never merged.
  for (size_t slot = 0; slot < values_.size(); ++slot) {
    const size_t at = pick(rng);
    by_light_[at % per_pixel / 3].push_back({at / per_pixel * 3 + at % 3, slot});
  }
}

void FieldValueSamples::take(int light, const std::vector<float>& rgb) {
  for (const Pick& p : by_light_[size_t(light)]) values_[p.slot] = rgb[p.offset];
}

FieldNoise estimate_build_noise(SensorNoise& sensor, const std::vector<TransferSample>& transfer,
                                const MergeNoiseModel& model, double simulated_full_well_e,
                                std::vector<double> led_irradiance,
                                const std::vector<float>& field_values,
                                std::vector<std::string>& warnings) {
  if (!sensor.read_measured) {
    warnings.push_back(
        "noise not measured: needs at least 2 dark frames in every exposure step "
        "(plan.dark_frames); the fits will use their default noise model");
    return {};
  }
  std::string method = "read: dark-frame pairs";
  sensor.shot_measured = solve_shot_per_level(transfer, model.steps, sensor.read_variance,
                                              &sensor.shot_per_level, &sensor.transfer_samples);
  if (sensor.shot_measured) {
    method += "; shot: photon transfer over bracket pairs";
  } else if (simulated_full_well_e > 0) {
    sensor.shot_per_level = 1.0 / simulated_full_well_e;
    method += "; shot: simulated sensor's full well (no usable bracket pair)";
  } else {
    warnings.push_back(
        "noise not measured: no pair of exposure steps left enough well-exposed samples for "
        "photon transfer; the fits will use their default noise model");
    return {};
  }
  if (led_irradiance.empty()) return {};
  std::nth_element(led_irradiance.begin(), led_irradiance.begin() + led_irradiance.size() / 2,
                   led_irradiance.end());
  const double median_irradiance = led_irradiance[led_irradiance.size() / 2];
  return fit_field_noise(sensor, model, median_irradiance, field_values, method);
}

}  // namespace ls::capture
