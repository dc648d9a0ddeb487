#include "app/jobs/capture_job.h"

#include <memory>
#include <optional>
#include <set>

#include "capture/exposure_choice.h"
#include "capture/reference_drift.h"
#include "capture/response.h"
#include "lightstage/backend_registry.h"
#include "lightstage/errors.h"
#include "lightstage/memory.h"
#include "lightstage/run_outputs.h"
#include "lightstage/session.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

void collect_dead_leds(const Session& session, CaptureJobSummary& summary) {
  for (const auto& [index, reason] : session.dead_leds()) {
    summary.dead_leds.emplace_back(session.stage().leds[size_t(index)].id, reason);
  }
}

// The drift the reference LED measured over each time step this run finished (`unfinished`:
// the steps with frames missing before it), so that a resume reads no step's shots again.
void report_drift(const Session& session, const std::set<int>& unfinished,
                  CaptureJobSummary& summary) {
  const Stage& stage = session.stage();
  if (stage.plan.reference_led < 0) return;
  const auto response = capture::ResponseCurve::given_or_linear(stage.camera);
  std::set<int> still_missing;
  for (const PlannedFrame& f : session.missing_frames()) still_missing.insert(f.key.time_step);
  for (const int t : unfinished) {
    if (!still_missing.count(t)) capture::build_drift(session, t, response, false, &summary.drift);
  }
}

// Each LED's exposures from an earlier session of the same stage: the bracket steps that keep
// every pixel's best exposure there.
void choose_exposures(const fs::path& previous_dir, Stage& stage, CaptureJobSummary& summary) {
  const Session previous = Session::open(previous_dir);
  const Stage& before = previous.stage();
  bool same = before.leds.size() == stage.leds.size() &&
              before.camera.bracket.size() == stage.camera.bracket.size() &&
              before.camera.width == stage.camera.width &&
              before.camera.height == stage.camera.height;
  for (size_t i = 0; same && i < stage.leds.size(); ++i)
    same = before.leds[i].id == stage.leds[i].id;
  for (size_t e = 0; same && e < stage.camera.bracket.size(); ++e) {
    same = before.camera.bracket[e].exposure_s == stage.camera.bracket[e].exposure_s &&
           before.camera.bracket[e].gain == stage.camera.bracket[e].gain;
  }
  if (!same) {
    throw InputError(previous_dir.string() +
                     ": --exposures-from needs a session of the same stage (LED ids, bracket "
                     "exposures and gains, camera size) as " +
                     stage.source);
  }
  if (stage.camera.response.kind == CameraResponse::Kind::kRecover) {
    throw InputError(stage.source +
                     ": camera.response: --exposures-from needs the response given (linear, "
                     "gamma or a table): recovering it needs every LED's whole bracket");
  }
  const capture::ExposureChoice choice = capture::choose_led_exposures(previous);
  stage.plan.led_exposures = choice.led_exposures;
  summary.led_frames_full = choice.frames_before;
  summary.led_frames_chosen = choice.frames_after;
  summary.exposure_s_full = choice.exposure_s_before;
  summary.exposure_s_chosen = choice.exposure_s_after;
}

// What a capture holds per pixel and channel whatever the back-end: a dark mean (float) per
// exposure of the bracket and the one being checked, and a frame three times over (captured,
// read back to be checked, encoded). Refused before any device opens or file is written.
void require_capture_memory(const Stage& stage) {
  const CameraSpec& camera = stage.camera;
  const std::size_t bytes_per_value =
      sizeof(float) * (camera.bracket.size() + 2) + 3 * sizeof(uint16_t);
  require_memory(std::size_t(camera.width) * std::size_t(camera.height) *
                     std::size_t(camera.channels) * bytes_per_value,
                 stage.source + ": camera.width, camera.height: a capture at " +
                     std::to_string(camera.width) + "x" + std::to_string(camera.height) + "x" +
                     std::to_string(camera.channels),
                 "capture at a lower resolution (camera.width, camera.height)");
}

}  // namespace

std::string CaptureOptions::validate() const {
  if (session_dir.empty()) return "give --out DIR (new session) or --resume DIR";
  if (resume && !stage_file.empty()) return "--resume uses the session's own stage: drop --stage";
  if (resume && !scene_file.empty()) return "--resume uses the session's own scene: drop --scene";
  if (resume && !exposures_from.empty()) {
    return "--resume keeps the session's own exposures: drop --exposures-from";
  }
  return {};
}

namespace {

// The names in `dir` (none when it is missing).
std::set<fs::path> entries_of(const fs::path& dir) {
  std::set<fs::path> names;
  std::error_code ignored;
  for (const auto& entry : fs::directory_iterator(dir, ignored)) names.insert(entry.path());
  return names;
}

// The capture itself; `session` and `writer_lock` are the caller's, so that it can clean up.
CaptureJobSummary capture_frames(const CaptureOptions& options, const CaptureCallbacks& callbacks,
                                 std::optional<Session>& session,
                                 std::optional<SessionWriterLock>& writer_lock) {
  CaptureJobSummary summary;
  OpenedBackend devices;
  if (options.resume) {
    // Locked before the journal is read (as the last writer left it); a folder that is no session
    // gets no lock file, and Session::open names what is missing.
    if (fs::exists(options.session_dir / "manifest.json")) writer_lock.emplace(options.session_dir);
    session.emplace(Session::open(options.session_dir));
    // What is trusted is read back first: a damaged frame is captured again, never kept.
    summary.frame_check = session->verify_frames();
    summary.frames_present_before = int(session->frames().size());
    summary.frames_missing_before = int(session->missing_frames().size());
    if (session->complete()) {
      summary.already_complete = true;
      // A kill after the last frame but before its step was judged: judge it now.
      judge_captured_steps(*session, SequencerOptions{}.dead_led_threshold);
      collect_dead_leds(*session, summary);
      return summary;
    }
    devices = open_session_backend(*session);
  } else {
    Stage stage = options.stage_file.empty() ? default_stage() : load_stage(options.stage_file);
    if (!options.exposures_from.empty()) choose_exposures(options.exposures_from, stage, summary);
    require_stage_files(stage);  // A capture that would end unbuildable: refused first.
    require_capture_memory(stage);
    const Backend& backend = backend_registry().find(stage.camera.backend, stage.source);
    if (!options.scene_file.empty() && backend.input_file_name.empty()) {
      throw InputError(options.scene_file.string() + ": the \"" + backend.name + "\" back-end (" +
                       stage.source + ": camera.backend) takes no scene file");
    }
    // The devices (and the scene they read) before anything is created; then a copy of the scene
    // in the session, so that it is self-contained and resumable from anywhere.
    devices = backend.open({stage, options.scene_file, options.seed});
    SessionInfo info;
    info.backend = stage.camera.backend;
    info.seed = options.seed;
    info.camera_settings = devices.camera->reported_settings();
    session.emplace(Session::create(options.session_dir, stage, info));
    writer_lock.emplace(options.session_dir);
    if (!options.scene_file.empty()) {
      fs::copy_file(options.scene_file, options.session_dir / backend.input_file_name,
                    fs::copy_options::overwrite_existing);
    }
  }

  const Stage& stage = session->stage();
  std::set<int> unfinished;  // Time steps with frames missing before this run.
  for (const PlannedFrame& f : session->missing_frames()) unfinished.insert(f.key.time_step);
  SequencerOptions sequencer;
  // A simulated clock needs no settling time and renders each time step at its plan time; in
  // real time the capture waits for each step's start as the hardware does.
  if (devices.simulated_time) sequencer.sleep = [](double) {};
  sequencer.wait_for_time_steps = !devices.simulated_time;
  sequencer.stop_requested = callbacks.stop_requested;
  sequencer.on_progress = callbacks.on_progress;
  sequencer.verify_frames = options.verify_frames;
  // The bracket check compares frames in linear units: a response table is read here (the
  // sequencer knows linear and gamma responses itself; one still to recover leaves it unchecked).
  if (stage.camera.response.kind == CameraResponse::Kind::kTable) {
    auto curve = std::make_shared<const capture::ResponseCurve>(capture::ResponseCurve::from_spec(
        stage.camera.response, stage.camera.bit_depth, stage.camera.channels));
    sequencer.to_linear = [curve](int dn, int c) { return double(curve->to_linear(dn, c)); };
  }
  const size_t problems_before = session->frame_problems().size();
  if (callbacks.on_start) callbacks.on_start(summary, int(plan_frames(stage).size()));
  summary.capture = run_capture(*session, *devices.lights, *devices.camera, sequencer);
  for (const TimeStepOverrun& o : summary.capture.overruns) {
    summary.overrun_step_times_s.push_back(stage.plan.step_time_s(o.time_step));
  }
  report_drift(*session, unfinished, summary);
  for (size_t k = problems_before; k < session->frame_problems().size(); ++k) {
    const FrameProblem& p = session->frame_problems()[k];
    summary.frame_problems.push_back(p.key.name(stage) + " (shot " + std::to_string(p.attempt + 1) +
                                     "): " + p.problem);
  }
  collect_dead_leds(*session, summary);
  return summary;
}

}  // namespace

CaptureJobSummary capture(const CaptureOptions& options, const CaptureCallbacks& callbacks) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("capture: " + problem);
  }
  // A new session that fails before its first frame (refused for its disk, a side file that does
  // not read) is removed with the folders made for it, or in a folder that was there, what it
  // added: there is nothing in it to resume. Session::create cleans up after itself.
  std::optional<RunOutputs> made;
  std::set<fs::path> before;
  if (!options.resume) {
    made.emplace(options.session_dir);
    before = entries_of(options.session_dir);
  }
  std::optional<Session> session;
  std::optional<SessionWriterLock> writer_lock;  // One capture writes a session at a time.
  try {
    CaptureJobSummary summary = capture_frames(options, callbacks, session, writer_lock);
    if (made) made->keep();
    return summary;
  } catch (...) {
    if (made && session && session->frames().empty()) {
      writer_lock.reset();
      for (const fs::path& entry : entries_of(options.session_dir)) {
        if (!before.contains(entry)) made->add(entry);
      }
    } else if (made) {
      made->keep();  // Frames to resume, or not this run's session (another capture's, say).
    }
    throw;
  }
}

}  // namespace ls::jobs
