// lightstage capture: stage file + back-end -> session directory, resumable.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>

#include "lightstage/backends.h"
#include "lightstage/cli/commands.h"
#include "lightstage/errors.h"
#include "lightstage/progress.h"
#include "lightstage/sequencer.h"
#include "lightstage/session.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"

namespace ls::cli {

namespace fs = std::filesystem;

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

}  // namespace

int capture_session(const CaptureRequest& request) {
  std::optional<Session> session;
  // Real devices ("aravis", "v4l2": LEDs on gpiod) are opened before a session is created or
  // resumed, so a missing chip, line or camera stops the command before anything is captured.
  Hardware hardware;
  if (request.resume) {
    session.emplace(Session::open(request.session_dir));
    if (session->complete()) {
      std::fprintf(stderr, "%s: session is already complete (%zu frames)\n",
                   request.session_dir.c_str(), session->frames().size());
      return 0;
    }
    std::fprintf(stderr, "resuming %s: %zu frames present, %zu missing\n",
                 request.session_dir.c_str(), session->frames().size(),
                 session->missing_frames().size());
    if (is_hardware_backend(session->info().backend)) hardware = open_hardware(session->stage());
  } else {
    const Stage stage =
        request.stage_file.empty() ? default_stage() : load_stage(request.stage_file);
    if (is_hardware_backend(stage.camera.backend)) hardware = open_hardware(stage);
    SessionInfo info;
    info.backend = stage.camera.backend;
    info.seed = request.seed;
    // Validate the scene before creating anything, then keep a copy in the session so that it
    // is self-contained and resumable from anywhere.
    if (!request.scene_file.empty()) (void)sim::load_scene(request.scene_file);
    session.emplace(Session::create(request.session_dir, stage, info));
    if (!request.scene_file.empty()) {
      fs::copy_file(request.scene_file, request.session_dir / "scene.json",
                    fs::copy_options::overwrite_existing);
    }
  }

  const Stage& stage = session->stage();
  SequencerOptions options;
  std::unique_ptr<sim::SimStage> sim_stage;
  LightController* lights = hardware.lights.get();
  Camera* camera = hardware.camera.get();
  if (camera == nullptr) {
    if (session->info().backend != "sim") {
      throw InputError(stage.source + ": camera.backend: expected \"sim\", \"aravis\" or " +
                       "\"v4l2\", got \"" + session->info().backend + "\"");
    }
    const fs::path scene_copy = request.session_dir / "scene.json";
    const sim::Scene scene =
        fs::exists(scene_copy) ? sim::load_scene(scene_copy) : sim::default_scene();
    sim_stage = std::make_unique<sim::SimStage>(stage, scene, session->info().seed);
    lights = &sim_stage->lights();
    camera = &sim_stage->camera();
    // The simulated stage needs no settling time, and renders each time step at its plan time;
    // in real time it waits for each step's start as the hardware does.
    if (!stage.camera.simulated.real_time) options.sleep = [](double) {};
  }
  options.wait_for_time_steps = sim_stage == nullptr || stage.camera.simulated.real_time;

  StopSignals signals;
  ProgressReporter progress("capture", long(plan_frames(stage).size()), request.quiet);
  options.stop_requested = &g_stop_requested;
  options.on_progress = [&](const CaptureProgress& p) { progress.update(p.done, p.current); };
  const CaptureSummary summary = run_capture(*session, *lights, *camera, options);
  progress.done();

  std::fprintf(stderr,
               "%s: %d frames captured this run, %d already present, %d camera retries, "
               "%.1f s\n",
               request.session_dir.c_str(), summary.frames_captured, summary.frames_already_present,
               summary.camera_retries, summary.seconds);
  for (const TimeStepOverrun& o : summary.overruns) {
    std::fprintf(stderr,
                 "warning: time step %d (scene time %g s) took %.2f s to capture, longer than its "
                 "interval of %g s to the next step\n",
                 o.time_step, stage.plan.step_time_s(o.time_step), o.capture_s, o.interval_s);
  }
  for (const auto& [index, reason] : session->dead_leds()) {
    std::fprintf(stderr, "warning: LED %d flagged dead: %s\n", stage.leds[index].id,
                 reason.c_str());
  }
  switch (summary.status) {
    case CaptureSummary::Status::kComplete:
      return 0;
    case CaptureSummary::Status::kInterrupted:
      std::fprintf(stderr, "interrupted: %s\nresume with: lightstage capture --resume %s\n",
                   summary.message.c_str(), request.session_dir.c_str());
      return kExitInterrupted;
    case CaptureSummary::Status::kCameraFailed:
      std::fprintf(stderr, "camera failure: %s\n", summary.message.c_str());
      return kExitHardwareError;
    case CaptureSummary::Status::kWriteFailed:
      std::fprintf(stderr, "storage failure: %s\nresume with: lightstage capture --resume %s\n",
                   summary.message.c_str(), request.session_dir.c_str());
      return kExitStorageError;
  }
  return 0;
}

void add_capture_command(CLI::App& app) {
  auto request = std::make_shared<CaptureRequest>();
  auto* cmd = app.add_subcommand(
      "capture",
      "Capture a one-light-at-a-time session: each LED on, its exposure bracket, off; dark "
      "frames; over the plan's time steps. Every frame is saved as it arrives; Ctrl-C stops "
      "cleanly (all LEDs off) and --resume completes only what is missing.");
  cmd->add_option("--stage", request->stage_file,
                  "Stage file (JSON: LEDs, camera, plan). Default: the built-in ~150-LED dome.")
      ->check(CLI::ExistingFile);
  cmd->add_option("--scene", request->scene_file,
                  "Scene file for the simulated stage (JSON). Default: the built-in demo scene.")
      ->check(CLI::ExistingFile);
  auto* out = cmd->add_option("--out", request->session_dir, "New session directory to create.");
  auto* resume =
      cmd->add_option("--resume", request->session_dir, "Existing session directory to complete.");
  out->excludes(resume);
  cmd->add_option("--seed", request->seed, "Noise seed of the simulated camera.")
      ->capture_default_str();
  cmd->add_flag("--quiet", request->quiet, "No progress output.");
  cmd->callback([request, out, resume] {
    if (out->count() == 0 && resume->count() == 0) {
      throw CLI::ValidationError("capture", "give --out DIR (new session) or --resume DIR");
    }
    request->resume = resume->count() > 0;
    const int code = capture_session(*request);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace ls::cli
