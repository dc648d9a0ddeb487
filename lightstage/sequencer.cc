#include "lightstage/sequencer.h"

#include <algorithm>
#include <chrono>
#include <map>
#include <sstream>
#include <thread>

#include "lightstage/errors.h"

namespace ls {

namespace {

// Switches every LED off when the capture leaves scope, however it leaves.
class AllOffGuard {
 public:
  explicit AllOffGuard(LightController& lights) : lights_(lights) { lights_.all_off(); }
  ~AllOffGuard() { lights_.all_off(); }
  AllOffGuard(const AllOffGuard&) = delete;
  AllOffGuard& operator=(const AllOffGuard&) = delete;

 private:
  LightController& lights_;
};

// Mean dark frame per (time step, exposure step) in DN, for the dead-LED check.
class DarkCache {
 public:
  explicit DarkCache(const Session& session) : session_(session) {}

  const std::vector<float>* get(int time_step, int exposure_index) {
    const auto key = std::make_pair(time_step, exposure_index);
    if (auto it = cache_.find(key); it != cache_.end()) return &it->second;
    std::vector<float> mean;
    int count = 0;
    for (int r = 0; r < session_.stage().plan.dark_frames; ++r) {
      const FrameKey k{time_step, -1, exposure_index, r};
      if (!session_.frames().count(k)) continue;
      const RawFrame f = session_.load_frame(k);
      if (mean.empty()) mean.assign(f.pixels.size(), 0.0f);
      if (mean.size() != f.pixels.size()) continue;
      for (size_t i = 0; i < mean.size(); ++i) mean[i] += f.pixels[i];
      ++count;
    }
    if (count == 0) return nullptr;
    for (auto& v : mean) v /= float(count);
    return &(cache_[key] = std::move(mean));
  }

 private:
  const Session& session_;
  std::map<std::pair<int, int>, std::vector<float>> cache_;
};

// 99.9th percentile of (frame - dark) as a fraction of full scale.
double bright_signal_fraction(const RawFrame& frame, const std::vector<float>& dark) {
  if (dark.size() != frame.pixels.size() || frame.pixels.empty()) return 1.0;
  std::vector<float> diff(frame.pixels.size());
  for (size_t i = 0; i < diff.size(); ++i) diff[i] = float(frame.pixels[i]) - dark[i];
  const size_t k = std::min(diff.size() - 1, size_t(0.999 * diff.size()));
  std::nth_element(diff.begin(), diff.begin() + k, diff.end());
  return diff[k] / double(frame.max_value());
}

// Flags LEDs that are dark while their neighbours are lit (see SequencerOptions).
void flag_dead_leds(Session& session, int time_step, double threshold) {
  const Stage& stage = session.stage();
  const auto& signals = session.led_signals();
  const int n = int(stage.leds.size());
  for (int i = 0; i < n; ++i) {
    const auto it = signals.find({time_step, i});
    if (it == signals.end() || it->second >= threshold) continue;
    // Neighbours: LEDs within 1.6x the angle to the nearest one.
    double nearest_cos = -1;
    for (int j = 0; j < n; ++j) {
      if (j != i)
        nearest_cos =
            std::max(nearest_cos, stage.leds[i].dir_in_stage.dot(stage.leds[j].dir_in_stage));
    }
    const double radius = 1.6 * std::acos(std::clamp(nearest_cos, -1.0, 1.0));
    std::vector<double> around;
    for (int j = 0; j < n; ++j) {
      const double angle = std::acos(
          std::clamp(stage.leds[i].dir_in_stage.dot(stage.leds[j].dir_in_stage), -1.0, 1.0));
      if (j == i || angle > radius) continue;
      if (const auto s = signals.find({time_step, j}); s != signals.end())
        around.push_back(s->second);
    }
    if (around.empty()) continue;
    // An LED on the edge of a dark region has dark neighbours too; a broken one is dark among
    // lit ones. Lit: above 10x the threshold.
    const auto lit =
        std::count_if(around.begin(), around.end(), [&](double v) { return v > 10 * threshold; });
    if (lit >= 0.8 * double(around.size())) {
      std::ostringstream reason;
      reason << "time step " << time_step << ": brightest frame exceeds the dark frame by "
             << it->second * 100 << "% of full scale while " << lit << " of its " << around.size()
             << " neighbours are lit";
      session.mark_dead_led(i, reason.str());
    }
  }
}

}  // namespace

CaptureSummary run_capture(Session& session, LightController& lights, Camera& camera,
                           const SequencerOptions& options) {
  const auto started = std::chrono::steady_clock::now();
  const Stage& stage = session.stage();
  auto sleep = options.sleep ? options.sleep : [](double s) {
    std::this_thread::sleep_for(std::chrono::duration<double>(s));
  };
  auto stop_requested = [&] {
    return options.stop_requested && options.stop_requested->load(std::memory_order_relaxed);
  };

  CaptureSummary summary;
  const std::vector<PlannedFrame> missing = session.missing_frames();
  const int total = int(plan_frames(stage).size());
  summary.frames_already_present = total - int(missing.size());
  DarkCache darks(session);

  auto finish = [&](CaptureSummary::Status status, const std::string& message) {
    summary.status = status;
    summary.message = message;
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    const char* state = status == CaptureSummary::Status::kComplete      ? "complete"
                        : status == CaptureSummary::Status::kInterrupted ? "interrupted"
                                                                         : "camera-failed";
    session.write_manifest(state);
    return summary;
  };

  session.write_manifest("capturing");
  AllOffGuard guard(lights);

  // Frames of one LED (or the dark frames of one time step) form a group: the LED goes on once,
  // the whole bracket is exposed, and it goes off before the next group.
  size_t i = 0;
  while (i < missing.size()) {
    const int t = missing[i].key.time_step;
    const int led = missing[i].key.led_index;
    size_t end = i;
    while (end < missing.size() && missing[end].key.time_step == t &&
           missing[end].key.led_index == led) {
      ++end;
    }
    if (stop_requested()) {
      return finish(CaptureSummary::Status::kInterrupted,
                    "stopped on request; all LEDs are off and every frame taken is saved");
    }
    if (led >= 0) {
      lights.set_light(led, true);
      if (stage.plan.settle_s > 0) sleep(stage.plan.settle_s);
    }
    double brightest = 0.0;
    for (size_t k = i; k < end; ++k) {
      const PlannedFrame& planned = missing[k];
      CapturedFrame frame;
      for (int attempt = 0;; ++attempt) {
        try {
          frame = camera.capture(planned.request);
          break;
        } catch (const CameraTimeout& e) {
          if (attempt >= stage.camera.retries) {
            lights.all_off();
            std::ostringstream msg;
            msg << "camera gave no frame for " << planned.key.name(stage) << " after "
                << attempt + 1 << " attempts (" << e.what()
                << "); all LEDs are off, every frame taken is saved; resume with --resume";
            return finish(CaptureSummary::Status::kCameraFailed, msg.str());
          }
          ++summary.camera_retries;
        }
      }
      session.record_frame(planned, frame);
      ++summary.frames_captured;
      if (led >= 0) {
        if (const auto* dark = darks.get(t, planned.key.exposure_index)) {
          brightest = std::max(brightest, bright_signal_fraction(frame.raw, *dark));
        } else {
          brightest = 1.0;  // No dark reference: cannot judge.
        }
      }
      if (options.on_progress) {
        options.on_progress({summary.frames_already_present + summary.frames_captured, total,
                             planned.key.name(stage)});
      }
    }
    if (led >= 0) {
      lights.set_light(led, false);
      // Only a whole bracket taken in this run tells how bright the LED is.
      if (end - i == stage.camera.bracket.size()) session.record_led_signal(t, led, brightest);
    }
    // Once the last LED of a time step is in, judge that step's dark LEDs.
    const bool step_done = end == missing.size() || missing[end].key.time_step != t;
    if (step_done && led >= 0) flag_dead_leds(session, t, options.dead_led_threshold);
    i = end;
  }
  return finish(CaptureSummary::Status::kComplete, "capture complete");
}

}  // namespace ls
