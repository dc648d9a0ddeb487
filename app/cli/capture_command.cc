// lightstage capture: stage file + back-end -> session directory, resumable.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <optional>

#include "app/cli/commands.h"
#include "app/cli/validators.h"
#include "app/jobs/capture_job.h"
#include "lightstage/progress.h"

namespace ls::cli {

namespace {

std::atomic<bool> g_stop_requested{false};

extern "C" void on_stop_signal(int) {
  if (g_stop_requested.exchange(true)) return;
  static const char msg[] =
      "\nstop requested: finishing the frame in flight, switching all LEDs off...\n";
  [[maybe_unused]] auto n = ::write(STDERR_FILENO, msg, sizeof msg - 1);
}

// Restores the previous handlers when the capture ends.
class StopSignals {
 public:
  StopSignals() {
    g_stop_requested = false;
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
  }
  ~StopSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }

 private:
  struct sigaction old_int_ {
  }, old_term_{};
};

// What a resume found when it read the saved frames back.
void print_frame_check(const jobs::CaptureOptions& options, const FrameCheck& check) {
  std::fprintf(stderr, "%s: %d saved frames read back (%.1f MiB), %zu damaged%s\n",
               options.session_dir.c_str(), check.verified, double(check.bytes_read) / (1 << 20),
               check.damaged.size(), check.damaged.empty() ? "" : ", to be captured again:");
  for (const std::string& damaged : check.damaged) std::fprintf(stderr, "  %s\n", damaged.c_str());
}

}  // namespace

int capture_session(const jobs::CaptureOptions& options, bool quiet) {
  StopSignals signals;
  std::optional<ProgressReporter> progress;
  jobs::CaptureCallbacks callbacks;
  callbacks.stop_requested = &g_stop_requested;
  callbacks.on_start = [&](const jobs::CaptureJobSummary& before, int total_frames) {
    if (options.resume) {
      print_frame_check(options, before.frame_check);
      std::fprintf(stderr, "resuming %s: %d frames present, %d missing\n",
                   options.session_dir.c_str(), before.frames_present_before,
                   before.frames_missing_before);
    }
    if (before.led_frames_full > 0) {
      std::fprintf(stderr,
                   "exposures chosen per LED from %s: %d LED frames per time step instead of %d, "
                   "%.2f s of exposure instead of %.2f s\n",
                   options.exposures_from.c_str(), before.led_frames_chosen, before.led_frames_full,
                   before.exposure_s_chosen, before.exposure_s_full);
    }
    progress.emplace("capture", long(total_frames), quiet);
  };
  callbacks.on_progress = [&](const std::string&, long done, long, const std::string& frame) {
    progress->update(done, frame);
  };
  const jobs::CaptureJobSummary job = jobs::capture(options, callbacks);
  if (job.already_complete) {
    print_frame_check(options, job.frame_check);
    for (const auto& [led_id, reason] : job.dead_leds) {
      std::fprintf(stderr, "warning: LED %d flagged dead: %s\n", led_id, reason.c_str());
    }
    std::fprintf(stderr, "%s: session is already complete (%d frames)\n",
                 options.session_dir.c_str(), job.frames_present_before);
    return 0;
  }
  progress->done();

  const CaptureSummary& summary = job.capture;
  std::fprintf(stderr,
               "%s: %d frames captured this run, %d already present, %d camera retries, "
               "%d frames shot again after failing their check, %.1f s\n",
               options.session_dir.c_str(), summary.frames_captured, summary.frames_already_present,
               summary.camera_retries, summary.frames_reshot, summary.seconds);
  for (const std::string& problem : job.frame_problems) {
    std::fprintf(stderr, "warning: %s\n", problem.c_str());
  }
  for (const std::string& drift : job.drift) std::fprintf(stderr, "warning: %s\n", drift.c_str());
  for (size_t i = 0; i < summary.overruns.size(); ++i) {
    const TimeStepOverrun& o = summary.overruns[i];
    std::fprintf(stderr,
                 "warning: time step %d (scene time %g s) took %.2f s to capture, longer than its "
                 "interval of %g s to the next step\n",
                 o.time_step, job.overrun_step_times_s[i], o.capture_s, o.interval_s);
  }
  for (const auto& [led_id, reason] : job.dead_leds) {
    std::fprintf(stderr, "warning: LED %d flagged dead: %s\n", led_id, reason.c_str());
  }
  switch (summary.status) {
    case CaptureSummary::Status::kComplete:
      return 0;
    case CaptureSummary::Status::kInterrupted:
      std::fprintf(stderr, "interrupted: %s\nresume with: lightstage capture --resume %s\n",
                   summary.message.c_str(), options.session_dir.c_str());
      return kExitInterrupted;
    case CaptureSummary::Status::kCameraFailed:
      std::fprintf(stderr, "camera failure: %s\n", summary.message.c_str());
      return kExitHardwareError;
    case CaptureSummary::Status::kDarkFramesLit:
      std::fprintf(stderr, "dark frames show light: %s\n", summary.message.c_str());
      return kExitHardwareError;
    case CaptureSummary::Status::kWriteFailed:
      std::fprintf(stderr, "storage failure: %s\nresume with: lightstage capture --resume %s\n",
                   summary.message.c_str(), options.session_dir.c_str());
      return kExitStorageError;
  }
  return 0;
}

void add_capture_command(CLI::App& app) {
  auto options = std::make_shared<jobs::CaptureOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand(
      "capture",
      "Capture a one-light-at-a-time session: each LED on, its exposure bracket, off; dark "
      "frames; over the plan's time steps. Every frame is saved as it arrives; Ctrl-C stops "
      "cleanly (all LEDs off) and --resume completes only what is missing.");
  cmd->add_option("--stage", options->stage_file,
                  "Stage file (JSON: LEDs, camera, plan). Default: the built-in ~150-LED dome.")
      ->check(CLI::ExistingFile);
  cmd->add_option("--scene", options->scene_file,
                  "Scene file for the simulated stage (JSON). Default: the built-in demo scene.")
      ->check(CLI::ExistingFile);
  auto* out = cmd->add_option("--out", options->session_dir, "New session directory to create.");
  auto* resume =
      cmd->add_option("--resume", options->session_dir, "Existing session directory to complete.");
  out->excludes(resume);
  cmd->add_option("--seed", options->seed, "Noise seed of the simulated camera.")
      ->capture_default_str()
      ->check(kSeed);
  cmd->add_option("--exposures-from", options->exposures_from,
                  "An earlier session of the same stage and scene: each LED is shot only at the "
                  "bracket steps that were the best exposure of its pixels there (fewer frames, "
                  "the same field within its noise).")
      ->check(CLI::ExistingDirectory);
  cmd->add_flag(
      "--no-frame-checks", [options](int64_t) { options->verify_frames = false; },
      "Save frames unchecked. By default each frame is checked on arrival (dark frames "
      "dark, a bracket's frames consistent with each other) and a bad one shot again; "
      "turn this off only for a camera whose frames do not follow the LEDs, such as "
      "Aravis' test-pattern Fake_1.");
  add_quiet_flag(*cmd, *quiet);
  cmd->callback([options, quiet, resume] {
    options->resume = resume->count() > 0;
    if (const std::string problem = options->validate(); !problem.empty()) {
      throw CLI::ValidationError("capture", problem);
    }
    const int code = capture_session(*options, *quiet);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace ls::cli
