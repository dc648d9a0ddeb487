#include "capture/build_field.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <thread>

#include "capture/light_calibration.h"
#include "capture/noise_estimate.h"
#include "capture/response.h"
#include "lightstage/errors.h"

namespace ls::capture {
namespace {

// LEDs whose brackets feed the response recovery (kRecover): a few views of the scene give the
// solver a wider spread of radiances than one.
constexpr int kRecoveryLeds = 3;
// Photon transfer (noise_estimate.h) uses the brackets of this many LEDs, spread over the capture
// order, and about this many pixels of each: plenty for a few dozen level bins.
constexpr int kTransferLeds = 12;
constexpr int kTransferPixelsPerLed = 10000;
// Field values sampled to fit the linear noise model where the data are.
constexpr size_t kNoiseFitValues = 20000;

std::string format_gamma(double gamma) {
  char text[32];
  std::snprintf(text, sizeof(text), "gamma %g", gamma);
  return text;
}

// One LED's bracket in this time step: a record per exposure step, null where the frame is absent.
struct LedFrames {
  int led_index = -1;
  std::vector<const FrameRecord*> records;
  bool complete() const {
    return std::all_of(records.begin(), records.end(), [](auto* r) { return r != nullptr; });
  }
};

ResponseCurve recover_from_session(const Session& session, const std::vector<LedFrames>& brackets,
                                   const std::vector<bool>& usable) {
  const Stage& stage = session.stage();
  // "Brightest" without reading every frame: the LEDs nearest the camera axis (front light reaches
  // what the camera sees) with the highest calibrated irradiance.
  std::vector<std::pair<double, size_t>> scored;
  for (size_t i = 0; i < brackets.size(); ++i) {
    if (!usable[i]) continue;
    const Led& led = stage.leds[brackets[i].led_index];
    const double facing = std::max(0.05, led.dir_in_stage.z());
    scored.push_back({-led.irradiance_rgb().mean() * facing, i});
  }
  if (scored.empty()) {
    throw InputError(session.dir().string() +
                     ": camera response 'recover' needs at least one LED with a complete bracket");
  }
  std::sort(scored.begin(), scored.end());
  scored.resize(std::min<size_t>(scored.size(), kRecoveryLeds));

  // The solver wants one static scene per exposure: put the chosen LEDs' frames side by side, so
  // each exposure step becomes one wide image of several lighting conditions.
  const size_t num_exposures = brackets[scored[0].second].records.size();
  std::vector<RawFrame> tiled(num_exposures);
  std::vector<double> exposure_gain(num_exposures);
  for (size_t e = 0; e < num_exposures; ++e) {
    std::vector<RawFrame> parts;
    for (const auto& [score, i] : scored) {
      parts.push_back(session.load_frame(brackets[i].records[e]->key));
    }
    const RawFrame& first = parts[0];
    for (const RawFrame& p : parts) {
      if (p.width != first.width || p.height != first.height || p.channels != first.channels ||
          p.bit_depth != first.bit_depth) {
        throw InputError(session.dir().string() + ": frames differ in size or format");
      }
    }
    RawFrame& t = tiled[e];
    t.width = first.width * int(parts.size());
    t.height = first.height;
    t.channels = first.channels;
    t.bit_depth = first.bit_depth;
    t.pixels.resize(size_t(t.width) * t.height * t.channels);
    const size_t part_row = size_t(first.width) * first.channels;
    for (int y = 0; y < t.height; ++y) {
      for (size_t p = 0; p < parts.size(); ++p) {
        std::copy_n(parts[p].pixels.data() + y * part_row, part_row,
                    t.pixels.data() + y * part_row * parts.size() + p * part_row);
      }
    }
    const FrameRecord* record = brackets[scored[0].second].records[e];
    exposure_gain[e] = record->exposure_s * record->gain;
  }
  std::vector<const RawFrame*> frames;
  for (const RawFrame& t : tiled) frames.push_back(&t);
  return recover_response(frames, exposure_gain);
}

double mean_value(const Image& image) {
  if (image.pixels.empty()) return 0.0;
  double sum = 0;
  for (const float v : image.pixels) sum += v;
  return sum / double(image.pixels.size());
}

// FieldNoise from the dark-frame read noise and photon transfer (noise_estimate.h), propagated
// through the merge at the median LED irradiance (the field stores one model for all LEDs).
FieldNoise estimate_field_noise(const ReflectanceField& field, const Stage& stage,
                                const std::vector<bool>& usable, const std::vector<int>& order,
                                const std::vector<NoiseStep>& steps, const MergeOptions& merge,
                                SensorNoise& sensor, const std::vector<TransferSample>& transfer,
                                BuildSummary* summary) {
  summary->sensor_noise = sensor;
  if (!sensor.read_measured) {
    summary->warnings.push_back(
        "noise not measured: needs at least 2 dark frames in every exposure step (plan.dark_frames)"
        "; the fits will use their default noise model");
    return {};
  }
  std::string method = "read: dark-frame pairs";
  sensor.shot_measured = solve_shot_per_level(transfer, steps, sensor.read_variance,
                                              &sensor.shot_per_level, &sensor.transfer_samples);
  if (sensor.shot_measured) {
    method += "; shot: photon transfer over bracket pairs";
  } else if (stage.camera.backend == "sim" && stage.camera.simulated.full_well_e > 0) {
    sensor.shot_per_level = 1.0 / stage.camera.simulated.full_well_e;
    method += "; shot: simulated sensor's full well (no usable bracket pair)";
  } else {
    summary->warnings.push_back(
        "noise not measured: no pair of exposure steps left enough well-exposed samples for "
        "photon transfer; the fits will use their default noise model");
    return {};
  }
  std::vector<double> irradiance;
  for (size_t i = 0; i < order.size(); ++i) {
    if (!usable[i]) continue;
    const Eigen::Vector3d e = stage.leds[order[i]].irradiance_rgb();
    irradiance.insert(irradiance.end(), {e.x(), e.y(), e.z()});
  }
  if (irradiance.empty()) return {};
  std::nth_element(irradiance.begin(), irradiance.begin() + irradiance.size() / 2,
                   irradiance.end());
  const double median_irradiance = irradiance[irradiance.size() / 2];
  const std::vector<float>& all = field.values();
  // Random rather than strided indices: a stride could fall in step with the 3 * lights layout.
  std::mt19937_64 rng(1);
  std::uniform_int_distribution<size_t> pick(0, all.empty() ? 0 : all.size() - 1);
  std::vector<float> values;
  for (size_t i = 0; i < std::min(all.size(), kNoiseFitValues); ++i)
    values.push_back(all[pick(rng)]);
  summary->sensor_noise = sensor;
  MergeNoiseModel model{steps, merge, stage.camera.radiometric_scale};
  return fit_field_noise(sensor, model, median_irradiance, values, method);
}

}  // namespace

ReflectanceField build_field(const Session& session, const BuildOptions& options,
                             BuildSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  const Stage& stage = session.stage();
  const CameraSpec& camera = stage.camera;
  const std::string where = session.dir().string();
  const int num_exposures = int(camera.bracket.size());
  if (num_exposures == 0)
    throw InputError(stage.source + ": camera.bracket: expected at least one step");
  if (options.time_step < 0 || options.time_step >= std::max(1, stage.plan.time_steps)) {
    throw InputError(where + ": time step " + std::to_string(options.time_step) +
                     " is outside the plan's " + std::to_string(stage.plan.time_steps) + " steps");
  }
  if (camera.channels != 1 && camera.channels != 3) {
    throw InputError(stage.source + ": camera.channels: expected 1 or 3, got " +
                     std::to_string(camera.channels));
  }
  if (!(camera.radiometric_scale > 0) || !std::isfinite(camera.radiometric_scale)) {
    throw InputError(stage.source + ": camera.radiometric_scale: expected a positive number, got " +
                     std::to_string(camera.radiometric_scale));
  }
  BuildSummary local_summary;
  BuildSummary& sum = summary ? *summary : local_summary;
  sum = BuildSummary{};

  // Index this time step's frames: dark frames per exposure step, each LED's bracket.
  const std::vector<int> order = stage.capture_order();
  std::map<int, size_t> position_of_led;
  std::vector<LedFrames> brackets(order.size());
  for (size_t i = 0; i < order.size(); ++i) {
    brackets[i].led_index = order[i];
    brackets[i].records.assign(num_exposures, nullptr);
    position_of_led[order[i]] = i;
  }
  std::vector<std::vector<FrameKey>> dark_keys(num_exposures);
  for (const auto& [key, record] : session.frames()) {
    if (key.time_step != options.time_step) continue;
    if (key.exposure_index < 0 || key.exposure_index >= num_exposures) continue;
    if (key.is_dark()) {
      dark_keys[key.exposure_index].push_back(key);
    } else if (key.repeat == 0) {
      auto it = position_of_led.find(key.led_index);
      if (it != position_of_led.end()) brackets[it->second].records[key.exposure_index] = &record;
    }
  }

  std::vector<FieldLight> lights(order.size());
  std::vector<bool> usable(order.size());
  for (size_t i = 0; i < order.size(); ++i) {
    const Led& led = stage.leds[order[i]];
    usable[i] = brackets[i].complete() && session.dead_leds().count(order[i]) == 0;
    lights[i] = FieldLight{led.id, led.dir_in_stage, usable[i]};
    if (led.distance_m) {
      lights[i].position_in_stage = *led.distance_m * led.dir_in_stage.normalized();
      ++sum.near_lights;
    }
    if (!usable[i]) sum.lights_missing.push_back(order[i]);
    if (usable[i]) {
      const Eigen::Vector3d e = led.irradiance_rgb();
      if (!(e.minCoeff() > 0) || !e.allFinite()) {
        throw InputError(stage.source + ": LED " + std::to_string(led.id) +
                         ": irradiance (intensity * color_gain) must be positive in every "
                         "channel to normalise the field, got " +
                         std::to_string(e.x()) + ", " + std::to_string(e.y()) + ", " +
                         std::to_string(e.z()));
      }
    }
  }

  // The response: from the stage file, or recovered from the brightest brackets.
  std::optional<ResponseCurve> response;
  switch (camera.response.kind) {
    case CameraResponse::Kind::kLinear:
      sum.response_used = "linear";
      break;
    case CameraResponse::Kind::kGamma:
      sum.response_used = format_gamma(camera.response.gamma);
      break;
    case CameraResponse::Kind::kTable:
      sum.response_used = "table " + camera.response.table_file.string();
      break;
    case CameraResponse::Kind::kRecover:
      sum.response_used = "recovered";
      response = recover_from_session(session, brackets, usable);
      break;
  }
  if (!response)
    response = ResponseCurve::from_spec(camera.response, camera.bit_depth, camera.channels);

  // The flat fields, validated before any frame is merged.
  std::optional<FlatFieldMaps> flat;
  if (!stage.calibration.flat_field.empty()) {
    flat = read_flat_field(stage.calibration.flat_field, stage);
    sum.flat_field = stage.calibration.flat_field.string();
    for (size_t i = 0; i < order.size(); ++i) {
      if (flat->by_led_id.count(stage.leds[order[i]].id)) ++sum.flat_field_lights;
    }
    if (sum.flat_field_lights < int(order.size())) {
      sum.warnings.push_back(
          sum.flat_field + ": holds flat fields for " + std::to_string(sum.flat_field_lights) +
          " of " + std::to_string(order.size()) + " LEDs; the others are taken as uniform");
    }
  }

  // Allocate the field first: it is the big allocation and refuses cleanly when it cannot fit.
  ReflectanceField field(camera.width, camera.height, std::move(lights));
  field.source = where;
  field.view = FieldView{camera.fov_y_deg, camera.distance_m, camera.ortho_height_m,
                         stage.calibration.reference_z_m};
  // Per-pixel factor of LED i: (|P - X| / |P|)^2 / flat(X) (build_field.h); empty when uniform.
  auto pixel_gain = [&](int i, std::vector<float>* gain) {
    const Led& led = stage.leds[order[i]];
    const auto& position = field.lights()[i].position_in_stage;
    const bool flat_here = flat && flat->by_led_id.count(led.id);
    gain->clear();
    if (!position && !flat_here) return;
    gain->resize(size_t(camera.width) * camera.height);
    const double d0_squared = position ? position->squaredNorm() : 1.0;
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        double g = 1.0;
        if (position) {
          const Eigen::Vector3d to_led =
              *position - reference_point(*field.view, camera.width, camera.height, x, y);
          g = to_led.squaredNorm() / d0_squared;
        }
        if (flat_here) g /= flat->at(led.id, x, y, camera.width, camera.height);
        (*gain)[size_t(y) * camera.width + x] = float(g);
      }
    }
  };
  for (size_t i = 0; i < order.size(); ++i) {
    if (usable[i]) {
      field.scene_time_s = brackets[i].records[0]->scene_time_s;
      break;
    }
  }

  auto check_size = [&](const RawFrame& frame, const FrameKey& key) {
    if (frame.width != camera.width || frame.height != camera.height ||
        frame.channels != camera.channels) {
      throw InputError(where + ": frame " + key.name(stage) + " is " + std::to_string(frame.width) +
                       "x" + std::to_string(frame.height) + "x" + std::to_string(frame.channels) +
                       " but the camera is " + std::to_string(camera.width) + "x" +
                       std::to_string(camera.height) + "x" + std::to_string(camera.channels));
    }
  };

  // Mean dark frame per exposure step (linearised), and the read noise from pairs of darks.
  std::vector<std::optional<Image>> darks(num_exposures);
  std::vector<NoiseStep> noise_steps(num_exposures);
  SensorNoise sensor;
  sensor.read_variance.assign(num_exposures, 0.0);
  sensor.read_measured = true;
  for (int e = 0; e < num_exposures; ++e) {
    noise_steps[e].exposure_s = camera.bracket[e].exposure_s;
    noise_steps[e].gain = camera.bracket[e].gain;
  }
  for (int e = 0; e < num_exposures; ++e) {
    if (dark_keys[e].empty()) {
      sensor.read_measured = false;
      sum.warnings.push_back("no dark frames for exposure step " + std::to_string(e) +
                             " at time step " + std::to_string(options.time_step) +
                             ": that step is not dark-subtracted");
      continue;
    }
    std::vector<RawFrame> raw;
    for (const FrameKey& key : dark_keys[e]) {
      raw.push_back(session.load_frame(key));
      check_size(raw.back(), key);
    }
    std::vector<const RawFrame*> pointers;
    for (const RawFrame& r : raw) pointers.push_back(&r);
    darks[e] = mean_dark(pointers, *response);
    noise_steps[e].dark_frames = int(raw.size());
    noise_steps[e].dark_level = mean_value(*darks[e]);
    if (raw.size() >= 2) {
      long long samples = 0;
      sensor.read_variance[e] = dark_read_variance(pointers, *response, &samples);
      sensor.dark_samples += samples;
    } else {
      sensor.read_measured = false;
    }
  }

  // Merge each LED's bracket. LEDs run in parallel (frame decoding is serial per file); the number
  // in flight is bounded so that frames of large cameras do not exhaust memory.
  const int width = camera.width;
  const int height = camera.height;
  const size_t frame_bytes = size_t(width) * height * camera.channels * sizeof(uint16_t);
  const size_t per_led_bytes =
      frame_bytes * num_exposures + size_t(width) * height * (camera.channels + 1) * sizeof(float);
  const size_t spare = available_memory_bytes() / 2;
  const int max_in_flight =
      int(std::clamp<size_t>(spare / std::max<size_t>(per_led_bytes, 1), 1,
                             std::max(1u, std::thread::hardware_concurrency())));
  const int num_lights = int(order.size());
  std::vector<Eigen::Array3f> scale(num_lights, Eigen::Array3f::Zero());
  for (int i = 0; i < num_lights; ++i) {
    if (!usable[i]) continue;
    const Eigen::Vector3d e = stage.leds[order[i]].irradiance_rgb();
    // Merged signal is "full scale per second at gain 1"; radiometric_scale turns it into radiance,
    // and dividing by the LED's irradiance gives R(x, l) per unit irradiance (1/sr).
    for (int c = 0; c < 3; ++c) scale[i][c] = float(camera.radiometric_scale / e[c]);
    // Saturation ceiling: a sample clipped in every exposure keeps the shortest exposure's value,
    // (linear - dark) / (exposure * gain) with linear >= saturation_level (hdr_merge.h), so no
    // clipped sample lies below (saturation_level - dark level) / (exposure * gain) of that step.
    int shortest = 0;
    auto exposure_gain = [&](int e) {
      return brackets[i].records[e]->exposure_s * brackets[i].records[e]->gain;
    };
    for (int e = 1; e < num_exposures; ++e) {
      if (exposure_gain(e) < exposure_gain(shortest)) shortest = e;
    }
    const double ceiling = (options.merge.saturation_level - noise_steps[shortest].dark_level) /
                           exposure_gain(shortest);
    if (ceiling > 0 && std::isfinite(ceiling)) {
      // With a per-pixel gain the ceiling varies over the image: the lowest one is kept, so that
      // no clipped sample passes for a measurement (a few near-ceiling ones are censored too).
      std::vector<float> gain;
      pixel_gain(i, &gain);
      const float lowest = gain.empty() ? 1.0f : *std::min_element(gain.begin(), gain.end());
      for (int c = 0; c < 3; ++c) {
        field.lights()[i].saturates_at[c] = float(ceiling) * scale[i][c] * lowest;
      }
    }
  }
  // LEDs whose brackets feed photon transfer.
  std::vector<bool> transfer_led(num_lights, false);
  {
    std::vector<int> candidates;
    for (int i = 0; i < num_lights; ++i) {
      if (usable[i]) candidates.push_back(i);
    }
    const size_t picks = std::min<size_t>(candidates.size(), kTransferLeds);
    for (size_t p = 0; p < picks; ++p)
      transfer_led[candidates[p * candidates.size() / picks]] = true;
  }
  const int transfer_stride = std::max(1, width * height / kTransferPixelsPerLed);
  std::vector<TransferSample> transfer;
  std::mutex transfer_mutex;
  std::atomic<long long> saturated_pixels{0};
  std::mutex progress_mutex;
  int done = 0;
  auto report = [&] {
    if (!options.on_progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    options.on_progress(++done, num_lights);
  };

  tbb::task_arena arena(max_in_flight);
  arena.execute([&] {
    tbb::parallel_for(0, num_lights, [&](int i) {
      if (!usable[i]) {
        report();
        return;
      }
      std::vector<RawFrame> raw(num_exposures);
      std::vector<BracketFrame> bracket(num_exposures);
      for (int e = 0; e < num_exposures; ++e) {
        const FrameRecord& record = *brackets[i].records[e];
        raw[e] = session.load_frame(record.key);
        check_size(raw[e], record.key);
        bracket[e] =
            BracketFrame{&raw[e], darks[e] ? &*darks[e] : nullptr, record.exposure_s, record.gain};
      }
      const Image merged = merge_bracket(bracket, *response, options.merge);
      if (transfer_led[i]) {
        std::vector<const RawFrame*> frames;
        std::vector<const Image*> step_darks;
        for (int e = 0; e < num_exposures; ++e) {
          frames.push_back(&raw[e]);
          step_darks.push_back(darks[e] ? &*darks[e] : nullptr);
        }
        std::vector<TransferSample> samples = transfer_samples(
            frames, step_darks, *response, noise_steps, options.merge, transfer_stride);
        std::lock_guard<std::mutex> lock(transfer_mutex);
        transfer.insert(transfer.end(), samples.begin(), samples.end());
      }
      const int in_channels = camera.channels + 1;
      std::vector<float> gain;
      pixel_gain(i, &gain);
      long long saturated = 0;
      for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
          const float* m = &merged.pixels[(size_t(y) * width + x) * in_channels];
          float* out = field.pixel(x, y) + 3 * i;
          const float g = gain.empty() ? 1.0f : gain[size_t(y) * width + x];
          for (int c = 0; c < 3; ++c) out[c] = m[camera.channels == 1 ? 0 : c] * scale[i][c] * g;
          saturated += m[in_channels - 1] == 0.0f;
        }
      }
      saturated_pixels += saturated;
      report();
    });
  });

  sum.lights_used = int(std::count(usable.begin(), usable.end(), true));
  const double samples = double(sum.lights_used) * width * height;
  sum.saturated_fraction = samples > 0 ? double(saturated_pixels.load()) / samples : 0.0;
  field.noise = estimate_field_noise(field, stage, usable, order, noise_steps, options.merge,
                                     sensor, transfer, &sum);
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return field;
}

}  // namespace ls::capture
