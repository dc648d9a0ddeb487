#include "capture/build_field.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <numeric>
#include <optional>
#include <random>
#include <thread>

#include "capture/band_spill.h"
#include "capture/build_checkpoint.h"
#include "capture/field_file.h"
#include "capture/led_frames.h"
#include "capture/light_calibration.h"
#include "capture/noise_estimate.h"
#include "capture/reference_drift.h"
#include "capture/response.h"
#include "lightstage/bands.h"
#include "lightstage/errors.h"

namespace ls::capture {
namespace {

// What merging one LED holds: the bracket's frames, the merge, the LED's image in field units and
// its per-pixel gain.
size_t merge_bytes_per_led(const CameraSpec& camera, int exposures) {
  const size_t pixels = size_t(camera.width) * size_t(camera.height);
  return pixels * camera.channels * sizeof(uint16_t) * size_t(exposures) +
         pixels * size_t(camera.channels + 1 + 3 + 1) * sizeof(float);
}

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

void check_camera(const Session& session, const BuildOptions& options) {
  const Stage& stage = session.stage();
  const CameraSpec& camera = stage.camera;
  if (camera.bracket.empty()) {
    throw InputError(stage.source + ": camera.bracket: expected at least one step");
  }
  if (options.time_step < 0 || options.time_step >= std::max(1, stage.plan.time_steps)) {
    throw InputError(session.dir().string() + ": time step " + std::to_string(options.time_step) +
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
}

// One build, phase by phase: index the frames, choose the response and flat fields, average the
// dark frames, then merge every LED's bracket into the field and estimate its noise.
class FieldBuild {
 public:
  // Where each merged LED image goes (field light i, rgb as SpillFile::put's).
  using LedSink = std::function<void(int i, const std::vector<float>& rgb)>;

  FieldBuild(const Session& session, const BuildOptions& options, BuildSummary& summary)
      : session_(session),
        stage_(session.stage()),
        camera_(stage_.camera),
        options_(options),
        sum_(summary),
        where_(session.dir().string()),
        num_exposures_(int(camera_.bracket.size())),
        order_(stage_.capture_order()) {}

  // The field in memory.
  ReflectanceField run() {
    prepare();
    // The field is the big allocation and refuses cleanly when it cannot fit.
    ReflectanceField field(camera_.width, camera_.height, header_.lights());
    merge_brackets([&](int i, const std::vector<float>& rgb) { field.set_light_image(i, rgb); });
    finish();
    copy_attributes(header_, field);
    return field;
  }

  // The field written to `out` in bands of band_rows rows (an earlier, killed run's, when it left
  // a checkpoint), through a spill file kept beside it until the field is written: a killed build
  // run again merges only the LEDs it had not finished.
  // Returns the band height used.
  int run_to_file(const std::filesystem::path& out, const ExrAttributes& attributes,
                  int band_rows) {
    prepare();
    const RankSplit& split = options_.split;
    BuildCheckpoint checkpoint(out, session_, options_);
    band_rows = agreed_band_rows(checkpoint.dir(), band_rows, split);
    SpillFile spill(out, camera_.width, camera_.height, int(order_.size()), band_rows,
                    checkpoint.spill_path());
    resume_.emplace(Resume{checkpoint, spill});
    const LedSink sink = [&](int i, const std::vector<float>& rgb) { spill.put(i, rgb); };
    merge_brackets(sink, [&](int i) { return split.mine(i); });
    if (split.split()) {
      split.barrier();  // Every rank's LEDs are in the spill, with their records.
      if (split.rank != 0) return band_rows;
      spill.reopen();  // Their images as they wrote them (a file system shared between nodes).
      // The other ranks' LEDs, from their records (merged here where one is missing); not
      // counted as resumed.
      const int resumed = resumed_lights_.load();
      merge_brackets(sink, [&](int i) { return !split.mine(i); });
      resumed_lights_ = resumed;
    }
    resume_.reset();
    finish();
    HalfCheck check;
    sum_.storage =
        spill.write_field(out, header_, attributes, options_.progress, options_.storage, &check);
    if (options_.storage != StorageChoice::kFloat) sum_.half_check = check;
    checkpoint.remove();
    return band_rows;
  }

 private:
  // Everything before the merge: the frames, lights, response, flat fields, darks and scales.
  void prepare() {
    brackets_ = index_led_frames(session_, options_.time_step, order_, &dark_keys_);
    header_ = ReflectanceField::without_values(camera_.width, camera_.height, field_lights());
    if (std::find(usable_.begin(), usable_.end(), true) == usable_.end()) {
      const std::filesystem::path frames = session_.dir() / "frames";
      const std::string found = std::filesystem::is_directory(frames)
                                    ? std::to_string(session_.frames().size()) + " frames found"
                                    : frames.string() + " is not a folder";
      throw InputError(where_ + ": no LED has a complete bracket of frames at time step " +
                       std::to_string(options_.time_step) + " (" + found +
                       "): nothing to build a field from");
    }
    choose_response();
    drift_ = build_drift(session_, options_.time_step, *response_, options_.correct_drift,
                         &sum_.warnings);
    read_flat_fields();
    header_.source = where_;
    header_.view = FieldView{camera_.fov_y_deg, camera_.distance_m, camera_.ortho_height_m,
                             stage_.calibration.reference_z_m};
    for (size_t i = 0; i < order_.size(); ++i) {
      if (usable_[i]) {
        for (const FrameRecord* record : brackets_[i].records) {
          if (record) header_.scene_time_s = record->scene_time_s;
        }
        break;
      }
    }
    average_darks();
    scale_lights(header_);
    noise_samples_.emplace(camera_.width, camera_.height, int(order_.size()), kNoiseFitValues);
    transfer_.assign(order_.size(), {});
  }

  // After the merge: the summary's counts and the field's noise.
  void finish() {
    sum_.lights_used = int(std::count(usable_.begin(), usable_.end(), true));
    sum_.resumed_lights = resumed_lights_.load();
    const double samples = double(sum_.lights_used) * camera_.width * camera_.height;
    sum_.saturated_fraction = samples > 0 ? double(saturated_pixels_.load()) / samples : 0.0;
    std::vector<TransferSample> transfer;  // In capture order: the same noise every build.
    size_t total = 0;
    for (const std::vector<TransferSample>& samples : transfer_) total += samples.size();
    transfer.reserve(total);
    for (std::vector<TransferSample>& samples : transfer_) {
      transfer.insert(transfer.end(), samples.begin(), samples.end());
      std::vector<TransferSample>().swap(samples);  // Not held twice.
    }
    header_.noise = estimate_noise(transfer);
  }

  // FieldNoise from the dark-frame read noise and photon transfer, at the LEDs' median
  // irradiance (capture/noise_estimate.h).
  FieldNoise estimate_noise(const std::vector<TransferSample>& transfer) {
    std::vector<double> irradiance;
    for (size_t i = 0; i < order_.size(); ++i) {
      if (!usable_[i]) continue;
      const Eigen::Vector3d e = stage_.leds[order_[i]].irradiance_rgb();
      irradiance.insert(irradiance.end(), {e.x(), e.y(), e.z()});
    }
    sum_.sensor_noise = sensor_;  // As measured before photon transfer, unless it succeeds.
    FieldNoise noise = estimate_build_noise(
        sensor_, transfer, {noise_steps_, options_.merge, camera_.radiometric_scale},
        camera_.backend == "sim" ? camera_.simulated.full_well_e : 0.0, std::move(irradiance),
        noise_samples_->values(), sum_.warnings);
    if (noise.measured) sum_.sensor_noise = sensor_;
    return noise;
  }

  std::vector<FieldLight> field_lights() {
    std::vector<FieldLight> lights(order_.size());
    usable_.resize(order_.size());
    for (size_t i = 0; i < order_.size(); ++i) {
      const Led& led = stage_.leds[order_[i]];
      usable_[i] = brackets_[i].complete() && session_.dead_leds().count(order_[i]) == 0;
      lights[i] = FieldLight{led.id, led.dir_in_stage, usable_[i]};
      if (led.distance_m) {
        lights[i].position_in_stage = *led.distance_m * led.dir_in_stage.normalized();
        ++sum_.near_lights;
      }
      if (!usable_[i]) sum_.lights_missing.push_back(order_[i]);
      if (usable_[i]) {
        const Eigen::Vector3d e = led.irradiance_rgb();
        if (!(e.minCoeff() > 0) || !e.allFinite()) {
          throw InputError(stage_.source + ": LED " + std::to_string(led.id) +
                           ": irradiance (intensity * color_gain) must be positive in every "
                           "channel to normalise the field, got " +
                           std::to_string(e.x()) + ", " + std::to_string(e.y()) + ", " +
                           std::to_string(e.z()));
        }
      }
    }
    return lights;
  }

  // The response: from the stage file, or recovered from the brightest brackets.
  void choose_response() {
    switch (camera_.response.kind) {
      case CameraResponse::Kind::kLinear:
        sum_.response_used = "linear";
        break;
      case CameraResponse::Kind::kGamma:
        sum_.response_used = format_gamma(camera_.response.gamma);
        break;
      case CameraResponse::Kind::kTable:
        sum_.response_used = "table " + camera_.response.table_file.string();
        break;
      case CameraResponse::Kind::kRecover:
        sum_.response_used = "recovered";
        response_ = recover_from_session(session_, brackets_, usable_);
        break;
    }
    if (!response_) {
      response_ = ResponseCurve::from_spec(camera_.response, camera_.bit_depth, camera_.channels);
    }
  }

  // The flat fields, validated before any frame is merged.
  void read_flat_fields() {
    if (stage_.calibration.flat_field.empty()) return;
    flat_ = read_flat_field(stage_.calibration.flat_field, stage_);
    sum_.flat_field = stage_.calibration.flat_field.string();
    for (size_t i = 0; i < order_.size(); ++i) {
      if (flat_->by_led_id.count(stage_.leds[order_[i]].id)) ++sum_.flat_field_lights;
    }
    if (sum_.flat_field_lights < int(order_.size())) {
      sum_.warnings.push_back(
          sum_.flat_field + ": holds flat fields for " + std::to_string(sum_.flat_field_lights) +
          " of " + std::to_string(order_.size()) + " LEDs; the others are taken as uniform");
    }
  }

  // Per-pixel factor of LED i: (|P - X| / |P|)^2 / flat(X) (build_field.h); empty when uniform.
  void pixel_gain(const ReflectanceField& field, int i, std::vector<float>* gain) const {
    const Led& led = stage_.leds[order_[i]];
    const auto& position = field.lights()[i].position_in_stage;
    const bool flat_here = flat_ && flat_->by_led_id.count(led.id);
    gain->clear();
    if (!position && !flat_here) return;
    gain->resize(size_t(camera_.width) * camera_.height);
    for (int y = 0; y < camera_.height; ++y) {
      for (int x = 0; x < camera_.width; ++x) {
        double g = 1.0;
        if (position) {
          g = near_light_gain(*field.view, camera_.width, camera_.height, x, y, *position,
                              position->norm());
        }
        if (flat_here) g /= flat_->at(led.id, x, y, camera_.width, camera_.height);
        (*gain)[size_t(y) * camera_.width + x] = float(g);
      }
    }
  }

  void check_size(const RawFrame& frame, const FrameKey& key) const {
    if (frame.width != camera_.width || frame.height != camera_.height ||
        frame.channels != camera_.channels) {
      throw InputError(where_ + ": frame " + key.name(stage_) + " is " +
                       std::to_string(frame.width) + "x" + std::to_string(frame.height) + "x" +
                       std::to_string(frame.channels) + " but the camera is " +
                       std::to_string(camera_.width) + "x" + std::to_string(camera_.height) + "x" +
                       std::to_string(camera_.channels));
    }
  }

  // Mean dark frame per exposure step (linearised), and the read noise from pairs of darks.
  void average_darks() {
    darks_.resize(num_exposures_);
    noise_steps_.resize(num_exposures_);
    sensor_.read_variance.assign(num_exposures_, 0.0);
    sensor_.read_measured = true;
    for (int e = 0; e < num_exposures_; ++e) {
      noise_steps_[e].exposure_s = camera_.bracket[e].exposure_s;
      noise_steps_[e].gain = camera_.bracket[e].gain;
    }
    for (int e = 0; e < num_exposures_; ++e) {
      if (dark_keys_[e].empty()) {
        sensor_.read_measured = false;
        sum_.warnings.push_back("no dark frames for exposure step " + std::to_string(e) +
                                " at time step " + std::to_string(options_.time_step) +
                                ": that step is not dark-subtracted");
        continue;
      }
      std::vector<RawFrame> raw;
      for (const FrameKey& key : dark_keys_[e]) {
        raw.push_back(session_.load_frame(key));
        check_size(raw.back(), key);
      }
      std::vector<const RawFrame*> pointers;
      pointers.reserve(raw.size());
      for (const RawFrame& r : raw) pointers.push_back(&r);
      darks_[e] = mean_dark(pointers, *response_);
      noise_steps_[e].dark_frames = int(raw.size());
      const std::vector<float>& dark = darks_[e]->pixels;
      noise_steps_[e].dark_level =
          std::accumulate(dark.begin(), dark.end(), 0.0) / double(std::max<size_t>(1, dark.size()));
      if (raw.size() >= 2) {
        long long samples = 0;
        sensor_.read_variance[e] = dark_read_variance(pointers, *response_, &samples);
        sensor_.dark_samples += samples;
      } else {
        sensor_.read_measured = false;
      }
    }
  }

  // Per LED: the factor from merged signal to field units, and its saturation ceiling.
  void scale_lights(ReflectanceField& field) {
    scale_.assign(order_.size(), Eigen::Array3f::Zero());
    for (size_t i = 0; i < order_.size(); ++i) {
      if (!usable_[i]) continue;
      const Eigen::Vector3d e = stage_.leds[order_[i]].irradiance_rgb();
      // Merged signal is "full scale per second at gain 1"; radiometric_scale turns it into
      // radiance, and dividing by the LED's irradiance gives R(x, l) per unit irradiance (1/sr).
      for (int c = 0; c < 3; ++c) scale_[i][c] = float(camera_.radiometric_scale / e[c]);
      // Saturation ceiling: a sample clipped in every exposure keeps the shortest exposure's
      // value, (linear - dark) / (exposure * gain) with linear >= saturation_level (hdr_merge.h),
      // so no clipped sample lies below (saturation_level - dark level) / (exposure * gain) of
      // that step.
      int shortest = -1;  // Of the frames this LED was shot at.
      auto exposure_gain = [&](int e) {
        return brackets_[i].records[e]->exposure_s * brackets_[i].records[e]->gain;
      };
      for (int e = 0; e < num_exposures_; ++e) {
        if (brackets_[i].records[e] && (shortest < 0 || exposure_gain(e) < exposure_gain(shortest)))
          shortest = e;
      }
      const double ceiling = (options_.merge.saturation_level - noise_steps_[shortest].dark_level) /
                             exposure_gain(shortest);
      if (ceiling > 0 && std::isfinite(ceiling)) {
        // With a per-pixel gain the ceiling varies over the image: the lowest one is kept, so that
        // no clipped sample passes for a measurement (a few near-ceiling ones are censored too).
        std::vector<float> gain;
        pixel_gain(field, int(i), &gain);
        const float lowest = gain.empty() ? 1.0f : *std::min_element(gain.begin(), gain.end());
        for (int c = 0; c < 3; ++c) {
          field.lights()[i].saturates_at[c] = float(ceiling) * scale_[i][c] * lowest;
        }
      }
    }
  }

  // LEDs whose brackets feed photon transfer: kTransferLeds spread over the capture order.
  std::vector<bool> transfer_leds() const {
    std::vector<bool> transfer_led(order_.size(), false);
    std::vector<int> candidates;
    for (size_t i = 0; i < order_.size(); ++i) {
      if (usable_[i] && brackets_[i].full()) candidates.push_back(int(i));
    }
    const size_t picks = std::min<size_t>(candidates.size(), kTransferLeds);
    for (size_t p = 0; p < picks; ++p) {
      transfer_led[candidates[p * candidates.size() / picks]] = true;
    }
    return transfer_led;
  }

  // Merges LED i's bracket into its channels of the field (and its photon-transfer samples).
  void merge_led(int i, bool with_transfer, int transfer_stride, const LedSink& sink) {
    const int width = camera_.width, height = camera_.height;
    std::vector<RawFrame> raw(num_exposures_);
    std::vector<BracketFrame> bracket;  // The steps this LED was shot at.
    for (int e = 0; e < num_exposures_; ++e) {
      if (!brackets_[i].records[e]) continue;
      const FrameRecord& record = *brackets_[i].records[e];
      raw[e] = session_.load_frame(record.key);
      check_size(raw[e], record.key);
      bracket.push_back(
          BracketFrame{&raw[e], darks_[e] ? &*darks_[e] : nullptr, record.exposure_s, record.gain});
    }
    const Image merged = merge_bracket(bracket, *response_, options_.merge);
    if (with_transfer) {
      std::vector<const RawFrame*> frames;
      std::vector<const Image*> step_darks;
      for (int e = 0; e < num_exposures_; ++e) {
        frames.push_back(&raw[e]);
        step_darks.push_back(darks_[e] ? &*darks_[e] : nullptr);
      }
      transfer_[size_t(i)] = transfer_samples(frames, step_darks, *response_, noise_steps_,
                                              options_.merge, transfer_stride);
    }
    const int in_channels = camera_.channels + 1;
    const float drift = drift_ ? float(drift_->output_at_led(i)) : 1.0f;
    std::vector<float> gain;
    pixel_gain(header_, i, &gain);
    std::vector<float> rgb(size_t(width) * height * 3);  // In field units.
    long long saturated = 0;
    for (size_t p = 0; p < size_t(width) * height; ++p) {
      const float* m = &merged.pixels[p * in_channels];
      const float g = (gain.empty() ? 1.0f : gain[p]) / drift;
      for (int c = 0; c < 3; ++c)
        rgb[3 * p + c] = m[camera_.channels == 1 ? 0 : c] * scale_[i][c] * g;
      saturated += m[in_channels - 1] == 0.0f;
    }
    saturated_pixels_ += saturated;
    noise_samples_->take(i, rgb);
    // Another LED's failure (or a stop) cancels the merges in flight: their nested loops stop
    // early, so the image is incomplete and must not be kept (a resumed build would take it).
    if (tbb::is_current_task_group_canceling()) return;
    sink(i, rgb);
    if (resume_) {
      resume_->spill.sync();  // The image is there before its record says so.
      resume_->checkpoint.save(i, {saturated, transfer_[size_t(i)]});
    }
  }

  // LED i from an earlier run's checkpoint, when it finished it: its image read back from the
  // spill and counted as merge_led counts it. False: it must be merged.
  bool resumed(int i) {
    if (!resume_) return false;
    const std::optional<BuildCheckpoint::Led> led = resume_->checkpoint.load(i);
    if (!led) return false;
    std::vector<float> rgb;
    resume_->spill.reread(i, rgb);
    saturated_pixels_ += led->saturated;
    transfer_[size_t(i)] = led->transfer;
    noise_samples_->take(i, rgb);
    ++resumed_lights_;
    return true;
  }

  // LEDs run in parallel (frame decoding is serial per file); the number in flight is bounded so
  // that frames of large cameras do not exhaust memory.
  // Only the LEDs `mine` takes, when given.
  void merge_brackets(const LedSink& sink, const std::function<bool(int)>& mine = {}) {
    const int width = camera_.width, height = camera_.height;
    const size_t per_led_bytes = merge_bytes_per_led(camera_, num_exposures_);
    const size_t spare = std::min(MemoryBudget::default_bytes(), options_.memory.bytes());
    const int max_in_flight =
        int(std::clamp<size_t>(spare / std::max<size_t>(per_led_bytes, 1), 1,
                               std::max(1u, std::thread::hardware_concurrency())));
    const int num_lights = int(order_.size());
    int total = 0;
    for (int i = 0; i < num_lights; ++i) total += !mine || mine(i);
    const std::vector<bool> transfer_led = transfer_leds();
    const int transfer_stride = std::max(1, width * height / kTransferPixelsPerLed);
    std::mutex progress_mutex;
    int done = 0;
    auto report = [&] {
      if (!options_.progress) return;
      std::lock_guard<std::mutex> lock(progress_mutex);
      options_.progress("build", ++done, total, {});
    };
    tbb::task_arena arena(max_in_flight);
    arena.execute([&] {
      tbb::parallel_for(0, num_lights, [&](int i) {
        if (mine && !mine(i)) return;
        if (usable_[i] && !resumed(i)) merge_led(i, transfer_led[i], transfer_stride, sink);
        report();
      });
    });
  }

  const Session& session_;
  const Stage& stage_;
  const CameraSpec& camera_;
  const BuildOptions& options_;
  BuildSummary& sum_;
  const std::string where_;
  const int num_exposures_;
  const std::vector<int> order_;  // Capture order: field light i is LED order_[i].
  std::vector<LedFrames> brackets_;
  std::vector<std::vector<FrameKey>> dark_keys_;
  std::vector<bool> usable_;
  std::optional<ResponseCurve> response_;
  std::optional<ReferenceDrift> drift_;  // Divided out (BuildOptions::correct_drift).
  std::optional<FlatFieldMaps> flat_;
  std::vector<std::optional<Image>> darks_;
  std::vector<NoiseStep> noise_steps_;
  SensorNoise sensor_;
  std::vector<Eigen::Array3f> scale_;
  std::vector<std::vector<TransferSample>> transfer_;  // Per field light.
  std::atomic<long long> saturated_pixels_{0};
  ReflectanceField header_;  // Lights, view, time and noise; no values.
  std::optional<FieldValueSamples> noise_samples_;
  // A build in bands: where merged LEDs are kept for a later run, and what an earlier one kept.
  struct Resume {
    BuildCheckpoint& checkpoint;
    SpillFile& spill;
  };
  std::optional<Resume> resume_;
  std::atomic<int> resumed_lights_{0};
};

// Runs a build with the summary (the caller's or a local one) cleared, and times it.
template <class Build>
auto timed(const Session& session, const BuildOptions& options, BuildSummary* summary,
           Build build) {
  const auto start = std::chrono::steady_clock::now();
  check_camera(session, options);
  BuildSummary local_summary;
  BuildSummary& sum = summary ? *summary : local_summary;
  sum = BuildSummary{};
  auto result = build(FieldBuild(session, options, sum));
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace

ReflectanceField build_field(const Session& session, const BuildOptions& options,
                             BuildSummary* summary) {
  return timed(session, options, summary, [](FieldBuild build) { return build.run(); });
}

int build_field_file(const Session& session, const BuildOptions& options,
                     const std::filesystem::path& out, const ExrAttributes& attributes,
                     BuildSummary* summary) {
  const CameraSpec& camera = session.stage().camera;
  const size_t row_bytes =
      ReflectanceField::bytes_for(camera.width, 1, int(session.stage().leds.size()));
  const size_t budget = options.memory.bytes();
  // The budget is shared: the merges of the LEDs in flight (a quarter of it, at least one LED),
  // then the band, held twice while it is written (as spilled, then pixel-major).
  const size_t per_led = merge_bytes_per_led(camera, int(camera.bracket.size()));
  const size_t in_flight = std::clamp<size_t>(budget / 4 / std::max<size_t>(per_led, 1), 1,
                                              std::max(1u, std::thread::hardware_concurrency()));
  BuildOptions banded = options;
  banded.memory = MemoryBudget(per_led * in_flight);
  const size_t band_budget = budget > per_led * in_flight ? budget - per_led * in_flight : 0;
  const int rows = rows_within(band_budget, 2 * row_bytes, camera.height);
  if (rows >= camera.height && !options.split.split()) {
    BuildSummary local;
    BuildSummary& sum = summary ? *summary : local;
    const ReflectanceField field = build_field(session, options, &sum);
    HalfCheck check;
    sum.storage = choose_storage(field, options.storage, &check);
    if (options.storage != StorageChoice::kFloat) sum.half_check = check;
    write_field(out, field, attributes, 0, sum.storage);
    return camera.height;
  }
  return timed(session, banded, summary,
               [&](FieldBuild build) { return build.run_to_file(out, attributes, rows); });
}

}  // namespace ls::capture
