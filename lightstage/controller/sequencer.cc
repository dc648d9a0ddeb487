#include "lightstage/controller/sequencer.h"

#include <sys/statvfs.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <sstream>
#include <thread>

#include "lightstage/controller/frame_checks.h"
#include "lightstage/controller/frame_writer.h"
#include "lightstage/direction_index.h"
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

// Mean dark frame per (time step, exposure step) in DN, for the dead-LED check: from the dark
// frames of this run as they are captured, else (a resumed capture) from the session's files.
class DarkCache {
 public:
  // With a writer, it is flushed before the session's files are read.
  DarkCache(const Session& session, FrameWriter* writer) : session_(session), writer_(writer) {}

  void add(const FrameKey& key, const RawFrame& frame) {
    Sum& sum = captured_[{key.time_step, key.exposure_index}];
    if (sum.total.empty()) sum.total.assign(frame.pixels.size(), 0.0f);
    if (sum.total.size() != frame.pixels.size()) return;
    for (size_t i = 0; i < frame.pixels.size(); ++i) sum.total[i] += frame.pixels[i];
    ++sum.count;
  }

  const std::vector<float>* get(int time_step, int exposure_index) {
    const auto key = std::make_pair(time_step, exposure_index);
    if (auto it = mean_.find(key); it != mean_.end()) return &it->second;
    std::vector<float> total;
    int count = 0;
    if (auto it = captured_.find(key); it != captured_.end()) {
      total = std::move(it->second.total);
      count = it->second.count;
      captured_.erase(it);
    } else {
      if (writer_) writer_->flush();  // The session is read only when nothing is in flight.
      for (int r = 0; r < session_.stage().plan.dark_frames; ++r) {
        const FrameKey k{time_step, -1, exposure_index, r};
        if (!session_.frames().count(k)) continue;
        const RawFrame f = session_.load_frame(k);
        if (total.empty()) total.assign(f.pixels.size(), 0.0f);
        if (total.size() != f.pixels.size()) continue;
        for (size_t i = 0; i < total.size(); ++i) total[i] += f.pixels[i];
        ++count;
      }
    }
    if (count == 0) return nullptr;
    for (auto& v : total) v /= float(count);
    return &(mean_[key] = std::move(total));
  }

 private:
  struct Sum {
    std::vector<float> total;
    int count = 0;
  };
  const Session& session_;
  FrameWriter* writer_;
  std::map<std::pair<int, int>, Sum> captured_;
  std::map<std::pair<int, int>, std::vector<float>> mean_;
};

// 99.9th percentile of (frame - dark) as a fraction of full scale, over at most ~64k samples (a
// strided subset: the check must not cost a large sensor milliseconds per frame).
double bright_signal_fraction(const RawFrame& frame, const std::vector<float>& dark) {
  if (dark.size() != frame.pixels.size() || frame.pixels.empty()) return 1.0;
  const size_t stride = std::max<size_t>(1, frame.pixels.size() / 65536);
  std::vector<float> diff;
  diff.reserve(frame.pixels.size() / stride + 1);
  for (size_t i = 0; i < frame.pixels.size(); i += stride) {
    diff.push_back(float(frame.pixels[i]) - dark[i]);
  }
  const size_t k = std::min(diff.size() - 1, size_t(0.999 * diff.size()));
  std::nth_element(diff.begin(), diff.begin() + k, diff.end());
  return diff[k] / double(frame.max_value());
}

// Refuses to start a capture that cannot fit on the disk: each missing frame is budgeted at its
// uncompressed size (noisy high-bit-depth frames hardly compress), plus its journal line.
void require_free_space(const Session& session, const std::vector<PlannedFrame>& missing) {
  if (missing.empty()) return;
  const CameraSpec& camera = session.stage().camera;
  const double frame_bytes =
      double(camera.width) * camera.height * camera.channels * (camera.bit_depth > 8 ? 2 : 1) +
      4096.0;
  const double needed = frame_bytes * double(missing.size()) + (1 << 20);
  struct statvfs fs {};
  if (::statvfs(session.dir().c_str(), &fs) != 0) return;  // Cannot tell: the writes will say.
  const double available = double(fs.f_bavail) * double(fs.f_frsize);
  if (available < needed) {
    char message[256];
    std::snprintf(message, sizeof message,
                  ": the %zu frames still to capture need up to %.1f MiB, but the disk has only "
                  "%.1f MiB free; free some space or capture to another disk",
                  missing.size(), needed / (1 << 20), available / (1 << 20));
    throw StorageError(session.dir().string() + message);
  }
}

// Each LED's neighbours on the dome: the LEDs within 1.6x the angle to its nearest one.
class LedNeighbours {
 public:
  explicit LedNeighbours(const Stage& stage) : of_(stage.leds.size()) {
    std::vector<Eigen::Vector3d> dirs;
    for (const Led& led : stage.leds) dirs.push_back(led.dir_in_stage.normalized());
    const DirectionIndex index(dirs);
    for (int i = 0; i < int(dirs.size()); ++i) {
      for (const int j : index.within(dirs[size_t(i)], 1.6 * index.nearest_other_angle(i))) {
        if (j != i) of_[size_t(i)].push_back(j);
      }
    }
  }
  const std::vector<int>& of(int led) const { return of_[size_t(led)]; }

 private:
  std::vector<std::vector<int>> of_;
};

// Whether every LED frame of time step t is in the session.
bool step_captured(const Session& session, int t) {
  const Stage& stage = session.stage();
  for (int led = 0; led < int(stage.leds.size()); ++led) {
    for (const int e : stage.exposures_of(led)) {
      if (!session.frames().count({t, led, e, 0})) return false;
    }
  }
  return true;
}

// An LED's brightest bracket frame above the dark frame, from its saved frames: for an LED whose
// bracket was split between runs, or whose signal line a kill cut off.
double saved_signal(const Session& session, DarkCache& darks, int t, int led) {
  double brightest = 0.0;
  for (const int e : session.stage().exposures_of(led)) {
    const std::vector<float>* dark = darks.get(t, e);
    if (!dark) return 1.0;  // No dark reference: cannot judge.
    brightest =
        std::max(brightest, bright_signal_fraction(session.load_frame({t, led, e, 0}), *dark));
  }
  return brightest;
}

// Judges time step t once all its LED frames are saved: records the signal of every LED that has
// none, then flags LEDs that are dark while their neighbours are lit (see SequencerOptions).
// Idempotent, so a step is judged again after any kill; nothing may be in flight in a FrameWriter.
void judge_step(Session& session, DarkCache& darks, const LedNeighbours& neighbours, int t,
                double threshold) {
  const Stage& stage = session.stage();
  const int n = int(stage.leds.size());
  for (int i = 0; i < n; ++i) {
    if (!session.led_signals().count({t, i})) {
      session.record_led_signal(t, i, saved_signal(session, darks, t, i));
    }
  }
  const auto& signals = session.led_signals();
  for (int i = 0; i < n; ++i) {
    const double signal = signals.at({t, i});
    if (signal >= threshold || session.dead_leds().count(i)) continue;
    std::vector<double> around;
    for (const int j : neighbours.of(i)) around.push_back(signals.at({t, j}));
    if (around.empty()) continue;
    // An LED on the edge of a dark region has dark neighbours too; a broken one is dark among
    // lit ones. Lit: above 10x the threshold.
    const auto lit =
        std::count_if(around.begin(), around.end(), [&](double v) { return v > 10 * threshold; });
    if (lit >= 0.8 * double(around.size())) {
      std::ostringstream reason;
      reason << "time step " << t << ": brightest frame exceeds the dark frame by " << signal * 100
             << "% of full scale while " << lit << " of its " << around.size()
             << " neighbours are lit";
      session.mark_dead_led(i, reason.str());
    }
  }
}

// judge_step for every time step whose LED frames are all saved.
void judge_saved_steps(Session& session, DarkCache& darks, const LedNeighbours& neighbours,
                       double threshold) {
  for (int t = 0; t < session.stage().plan.time_steps; ++t) {
    if (step_captured(session, t)) judge_step(session, darks, neighbours, t, threshold);
  }
}

// Host time for FrameTiming: nanoseconds since the Unix epoch.
int64_t unix_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// The camera's response inverted when the stage gives it without a file (linear, gamma); empty
// otherwise (a table file, a response still to be recovered from the frames).
DnToLinear response_inverse(const CameraSpec& camera) {
  const double max_dn = double((1u << camera.bit_depth) - 1u);
  switch (camera.response.kind) {
    case CameraResponse::Kind::kLinear:
      return [max_dn](int dn, int) { return dn / max_dn; };
    case CameraResponse::Kind::kGamma: {
      const double gamma = camera.response.gamma;
      return [max_dn, gamma](int dn, int) { return std::pow(dn / max_dn, gamma); };
    }
    case CameraResponse::Kind::kTable:
    case CameraResponse::Kind::kRecover:
      break;
  }
  return {};
}

// The camera gave no frame after its retries: the capture stops, resumable.
struct CameraGaveUp {
  std::string message;
};

// Dark frames kept showing light after their re-shoots: the capture stops, resumable.
struct DarkFramesLit {
  std::string message;
};

// One run of the sequencer over a session's missing frames.
class CaptureRun {
 public:
  CaptureRun(Session& session, LightController& lights, Camera& camera,
             const SequencerOptions& options)
      : session_(session),
        stage_(session.stage()),
        lights_(lights),
        camera_(camera),
        options_(options),
        started_(std::chrono::steady_clock::now()),
        missing_(session.missing_frames()),
        total_(int(plan_frames(stage_).size())) {
    sleep_ = options.sleep ? options.sleep : [](double s) {
      std::this_thread::sleep_for(std::chrono::duration<double>(s));
    };
    clock_s_ = options.clock_s ? options.clock_s : [] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
          .count();
    };
    summary_.frames_already_present = total_ - int(missing_.size());
    to_linear_ = options.to_linear ? options.to_linear : response_inverse(stage_.camera);
  }

  CaptureSummary run() {
    require_free_space(session_, missing_);  // Before any LED is switched on.
    const LedNeighbours neighbours(stage_);
    writer_.emplace(session_);
    DarkCache darks(session_, &*writer_);
    // Steps a killed run finished without judging them (or all their LEDs): judged now.
    judge_saved_steps(session_, darks, neighbours, options_.dead_led_threshold);
    session_.write_manifest("capturing");
    AllOffGuard guard(lights_);
    try {
      // Frames of one LED's bracket (or the dark frames of one time step) form a group: the LED
      // goes on once, the whole bracket is exposed, and it goes off before the next group.
      for (size_t i = 0; i < missing_.size();) {
        const int t = missing_[i].key.time_step;
        const int led = missing_[i].key.led_index;
        size_t end = i;
        while (end < missing_.size() && missing_[end].key.time_step == t &&
               missing_[end].key.led_index == led &&
               (led < 0 || missing_[end].key.repeat == missing_[i].key.repeat)) {
          ++end;
        }
        if (t != current_step_) begin_step(t);
        if (stop_requested()) {
          return finish(CaptureSummary::Status::kInterrupted,
                        "stopped on request; all LEDs are off and every frame taken is saved");
        }
        capture_group(i, end, darks);
        // Once the last LED of a time step is in, judge that step's dark LEDs.
        const bool step_done = end == missing_.size() || missing_[end].key.time_step != t;
        if (step_done && led >= 0) {
          writer_->flush();  // The session is touched only when nothing is in flight.
          judge_step(session_, darks, neighbours, t, options_.dead_led_threshold);
        }
        i = end;
      }
      if (current_step_ >= 0) end_step(current_step_);
    } catch (const CameraGaveUp& e) {
      return finish(CaptureSummary::Status::kCameraFailed, e.message);
    } catch (const DarkFramesLit& e) {
      return finish(CaptureSummary::Status::kDarkFramesLit, e.message);
    } catch (const InputError& e) {
      // Only the frame writer throws InputError here: the disk is full or not writable.
      return finish(CaptureSummary::Status::kWriteFailed, cannot_save(e.what()));
    }
    return finish(CaptureSummary::Status::kComplete, "capture complete");
  }

 private:
  std::string cannot_save(const std::string& why) const {
    // A full disk wants space; a session whose frames/ is not a folder wants it moved aside; a
    // session folder that is gone (deleted, moved, unmounted) wants it back.
    const std::filesystem::path frames = session_.dir() / "frames";
    std::error_code ec;
    const std::string fix =
        !std::filesystem::is_directory(session_.dir(), ec)
            ? "the session folder " + session_.dir().string() +
                  " is gone (deleted, moved or unmounted): restore it and resume with --resume"
        : std::filesystem::is_directory(frames, ec)
            ? "free space and resume with --resume"
            : frames.string() + " is not a folder: move it aside and resume with --resume";
    return "cannot save frames: " + why +
           "; all LEDs are off and every frame saved before that is kept; " + fix;
  }

  bool stop_requested() const {
    return options_.stop_requested && options_.stop_requested->load(std::memory_order_relaxed);
  }

  // Every exit: LEDs off (here and by the guard), then whatever is queued saved before the
  // manifest says how the capture ended.
  CaptureSummary finish(CaptureSummary::Status status, std::string message) {
    lights_.all_off();
    try {
      writer_->flush();
    } catch (const std::exception& e) {
      if (status != CaptureSummary::Status::kWriteFailed) {
        status = CaptureSummary::Status::kWriteFailed;
        message = cannot_save(e.what());
      }
    }
    writer_.reset();
    summary_.frames_captured = int(session_.frames().size()) - summary_.frames_already_present;
    summary_.status = status;
    summary_.message = message;
    summary_.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
    const char* state = status == CaptureSummary::Status::kComplete       ? "complete"
                        : status == CaptureSummary::Status::kInterrupted  ? "interrupted"
                        : status == CaptureSummary::Status::kCameraFailed ? "camera-failed"
                        : status == CaptureSummary::Status::kWriteFailed  ? "write-failed"
                                                                          : "dark-frames-lit";
    try {
      session_.write_manifest(state);
    } catch (const std::exception& e) {
      // The journal, not the manifest, says what was captured; a stale manifest costs nothing.
      summary_.message += std::string(" (manifest not updated: ") + e.what() + ")";
    }
    return summary_;
  }

  void begin_step(int t) {
    if (current_step_ >= 0) end_step(current_step_);
    if (current_step_ < 0) {
      schedule_origin_s_ = clock_s_() - stage_.plan.step_time_s(t);
    } else if (options_.wait_for_time_steps) {
      // Wait in short sleeps so that a stop request is seen.
      const double start_s = schedule_origin_s_ + stage_.plan.step_time_s(t);
      // Within a microsecond is on time (and a sleep too short to move the clock ends).
      for (double left = start_s - clock_s_(); left > 1e-6; left = start_s - clock_s_()) {
        if (stop_requested()) break;
        sleep_(std::min(left, 0.1));
      }
    }
    current_step_ = t;
    step_started_s_ = clock_s_();
  }

  void end_step(int step) {
    const double took_s = clock_s_() - step_started_s_;
    const double interval_s = stage_.plan.step_interval_s(step);
    if (interval_s > 0 && took_s > interval_s) {
      const TimeStepOverrun overrun{step, took_s, interval_s};
      writer_->flush();  // The session is touched only when nothing is in flight.
      session_.record_time_step_overrun(overrun);
      summary_.overruns.push_back(overrun);
    }
  }

  CapturedFrame capture_with_retries(const PlannedFrame& planned) {
    for (int attempt = 0;; ++attempt) {
      try {
        const int64_t requested_ns = unix_ns();
        CapturedFrame frame = camera_.capture(planned.request);
        frame.timing.requested_ns = requested_ns;
        frame.timing.delivered_ns = unix_ns();
        frame.timing.led_on_ns = led_on_ns_;
        return frame;
      } catch (const CameraTimeout& e) {
        if (attempt >= stage_.camera.retries) {
          lights_.all_off();
          std::ostringstream msg;
          msg << "camera gave no frame for " << planned.key.name(stage_) << " after " << attempt + 1
              << " attempts (" << e.what()
              << "); all LEDs are off, every frame taken is saved; resume with --resume";
          throw CameraGaveUp{msg.str()};
        }
        ++summary_.camera_retries;
      }
    }
  }

  // A dark frame, checked for light and shot again while it shows some (frame_checks.h).
  CapturedFrame capture_dark(const PlannedFrame& planned) {
    for (int attempt = 0;; ++attempt) {
      CapturedFrame frame = capture_with_retries(planned);
      if (!options_.verify_frames) return frame;
      std::string problem = dark_frame_problem(frame.raw, options_.dark_frame_light_threshold);
      if (problem.empty()) return frame;
      writer_->record_frame_problem({planned.key, attempt, problem});
      if (attempt >= options_.frame_reshoots) {
        throw DarkFramesLit{"dark frame " + planned.key.name(stage_) + " after " +
                            std::to_string(attempt + 1) + " shots: " + problem +
                            "; all LEDs are off and every frame taken is saved; check the LED "
                            "lines and the room, then resume with --resume"};
      }
      ++summary_.frames_reshot;
      lights_.all_off();  // Again: a line that did not switch off.
    }
  }

  // Checks the bracket of one LED (frames of missing_[i, ...)) and shoots again the frames that
  // disagree with the others. The problem left after the re-shoots, or "" when they agree.
  std::string verify_bracket(size_t i, std::vector<CapturedFrame>& frames, DarkCache& darks) {
    for (int attempt = 0;; ++attempt) {
      const std::vector<std::string> problems = bracket_check(i, frames, darks);
      std::string last;
      for (size_t k = 0; k < frames.size(); ++k) {
        if (problems[k].empty()) continue;
        writer_->record_frame_problem({missing_[i + k].key, attempt, problems[k]});
        last = missing_[i + k].key.name(stage_) + ": " + problems[k];
      }
      if (last.empty() || attempt >= options_.frame_reshoots) return last;
      for (size_t k = 0; k < frames.size(); ++k) {
        if (problems[k].empty()) continue;
        frames[k] = capture_with_retries(missing_[i + k]);
        ++summary_.frames_reshot;
      }
    }
  }

  // What is wrong with each of the frames of one LED's bracket (missing_[i, ...)); see
  // bracket_problems. All "" when frames are not checked.
  std::vector<std::string> bracket_check(size_t i, const std::vector<CapturedFrame>& frames,
                                         DarkCache& darks) {
    if (!options_.verify_frames || !to_linear_) return std::vector<std::string>(frames.size());
    std::vector<BracketFrame> bracket;
    for (size_t k = 0; k < frames.size(); ++k) {
      const FrameKey& key = missing_[i + k].key;
      bracket.push_back({&frames[k].raw, frames[k].exposure_s, frames[k].gain,
                         darks.get(key.time_step, key.exposure_index), key.exposure_index});
    }
    return bracket_problems(bracket, to_linear_);
  }

  // The group's frames taken before the camera gave up or a dark frame stayed lit: the darks
  // (checked one by one) and those of an LED's frames that agree with each other, or the only one.
  void save_partial_group(size_t i, std::vector<CapturedFrame>& frames, DarkCache& darks) {
    const std::vector<std::string> problems = missing_[i].key.led_index >= 0
                                                  ? bracket_check(i, frames, darks)
                                                  : std::vector<std::string>(frames.size());
    for (size_t k = 0; k < frames.size(); ++k) {
      if (problems[k].empty()) writer_->write(missing_[i + k], std::move(frames[k]));
    }
  }

  // The frames missing_[i, end) of one LED (or the darks of one time step), checked before they
  // are saved.
  void capture_group(size_t i, size_t end, DarkCache& darks) {
    const int t = missing_[i].key.time_step;
    const int led = missing_[i].key.led_index;
    led_on_ns_ = 0;
    if (led >= 0) {
      lights_.set_light(led, true);
      led_on_ns_ = unix_ns();
      if (stage_.plan.settle_s > 0) sleep_(stage_.plan.settle_s);
    }
    std::vector<CapturedFrame> frames;
    std::string still_bad;  // What an LED's bracket shows after its re-shoots.
    try {
      for (size_t k = i; k < end; ++k) {
        frames.push_back(led >= 0 ? capture_with_retries(missing_[k]) : capture_dark(missing_[k]));
        if (options_.on_progress) {
          options_.on_progress("capture",
                               summary_.frames_already_present + frames_taken_ + long(k - i) + 1,
                               total_, missing_[k].key.name(stage_));
        }
      }
      if (led >= 0) still_bad = verify_bracket(i, frames, darks);
    } catch (...) {
      if (led >= 0) {
        lights_.all_off();
        const int64_t led_off_ns = unix_ns();
        for (CapturedFrame& frame : frames) frame.timing.led_off_ns = led_off_ns;
      }
      try {
        save_partial_group(i, frames, darks);  // Nothing captured is lost.
      } catch (...) {
        // The disk refused them too: the first failure is the one to report.
      }
      throw;
    }
    if (led >= 0) {
      lights_.set_light(led, false);
      const int64_t led_off_ns = unix_ns();
      for (CapturedFrame& frame : frames) frame.timing.led_off_ns = led_off_ns;
    }
    double brightest = 0.0;
    for (size_t k = i; k < end; ++k) {
      const PlannedFrame& planned = missing_[k];
      CapturedFrame& frame = frames[k - i];
      if (led >= 0) {
        if (const auto* dark = darks.get(t, planned.key.exposure_index)) {
          brightest = std::max(brightest, bright_signal_fraction(frame.raw, *dark));
        } else {
          brightest = 1.0;  // No dark reference: cannot judge.
        }
      } else {
        darks.add(planned.key, frame.raw);
      }
      writer_->write(planned, std::move(frame));
    }
    frames_taken_ += int(end - i);
    if (led < 0) return;
    if (!still_bad.empty()) {
      // Kept (the plan completes) but left out of the field, as a dead LED is.
      writer_->mark_dead_led(led, "time step " + std::to_string(t) + ": its bracket still " +
                                      "disagrees after " + std::to_string(options_.frame_reshoots) +
                                      " re-shoots: " + still_bad);
    }
    // Only a whole bracket taken in this run tells how bright the LED is; a split one is
    // judged from its saved frames (judge_step).
    if (end - i == stage_.exposures_of(led).size() && missing_[i].key.repeat == 0) {
      writer_->record_led_signal(t, led, brightest);
    }
  }

  Session& session_;
  const Stage& stage_;
  LightController& lights_;
  Camera& camera_;
  const SequencerOptions& options_;
  const std::chrono::steady_clock::time_point started_;
  const std::vector<PlannedFrame> missing_;
  const int total_;
  std::function<void(double)> sleep_;
  std::function<double()> clock_s_;
  DnToLinear to_linear_;   // Empty: the response is not known, and brackets are not checked.
  int64_t led_on_ns_ = 0;  // When the LED of the group being captured went on (FrameTiming).
  CaptureSummary summary_;
  std::optional<FrameWriter> writer_;
  int frames_taken_ = 0;
  // Time steps: the one being captured, when it began (clock_s) and the schedule's origin.
  int current_step_ = -1;
  double step_started_s_ = 0.0, schedule_origin_s_ = 0.0;
};

}  // namespace

void judge_captured_steps(Session& session, double dead_led_threshold) {
  DarkCache darks(session, nullptr);
  judge_saved_steps(session, darks, LedNeighbours(session.stage()), dead_led_threshold);
}

CaptureSummary run_capture(Session& session, LightController& lights, Camera& camera,
                           const SequencerOptions& options) {
  return CaptureRun(session, lights, camera, options).run();
}

}  // namespace ls
