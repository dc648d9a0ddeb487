#pragma once
// Drives a capture: LED on, bracket, LED off, with dark frames, over time steps. Frames are saved
// by a FrameWriter thread while the next ones are exposed; whatever the exit (done, stopped,
// camera or disk failure), all LEDs go off and every frame taken is saved, or re-captured on
// resume if the disk refused it. A capture that cannot fit on the disk is refused before it starts
// (InputError).
#include <atomic>
#include <functional>
#include <string>
#include <vector>

#include "lightstage/controller/frame_checks.h"
#include "lightstage/hardware.h"
#include "lightstage/progress.h"
#include "lightstage/session.h"

namespace ls {

struct SequencerOptions {
  // Set asynchronously (e.g. by a SIGINT handler); checked before every frame.
  const std::atomic<bool>* stop_requested = nullptr;
  // Phase "capture": frames in the session (this run and earlier runs) of the plan's; the item is
  // the name of the frame just written.
  ProgressFn on_progress;
  // Dead LEDs. An LED is dark when its brightest bracket frame exceeds the dark frame by less than
  // dead_led_threshold of full scale (99.9th percentile). A dark LED is judged broken, and flagged,
  // only when nearly all its neighbours on the dome (80%; those within 1.6x the angle to its
  // nearest LED) are clearly lit (> 10x the threshold): a whole dark region is the scene not being
  // lit from there (LEDs behind an opaque backdrop), which is data, not a fault. Judged once every
  // LED of a time step is captured, and again on resume (judge_captured_steps); the capture
  // continues.
  double dead_led_threshold = 0.002;
  // Frames are checked as they arrive (frame_checks.h), before they are saved, and a bad one is
  // shot again, at most frame_reshoots times: a dark frame with light in it, a frame that
  // disagrees with the rest of its LED's bracket. Each rejection is journaled
  // (Session::frame_problems) and counted. An LED whose bracket still disagrees after its
  // re-shoots is marked dead (its frames kept, left out of the field); a dark frame still lit
  // stops the capture (kDarkFramesLit), resumable once the room is dark.
  bool verify_frames = true;
  int frame_reshoots = 2;
  double dark_frame_light_threshold = 0.01;  // Of full scale; see dark_frame_problem.
  // The camera's response inverted, for the bracket check. Empty: the stage's own when it needs no
  // file (linear, gamma); with a table file or a response still to recover, brackets go unchecked.
  DnToLinear to_linear;
  // Sleeps for plan.settle_s and inter-step waits; tests replace it to run instantly.
  std::function<void(double seconds)> sleep;
  // Time steps in real time (hardware, or the simulator's camera.simulated.real_time): the first
  // frame of step t waits until its start time, start = when this run began its first step +
  // (step_time_s(t) - step_time_s(that first step)). Otherwise steps follow each other at once and
  // the plan times are only the scene times the frames carry (the simulator renders them).
  bool wait_for_time_steps = false;
  // Monotonic clock in seconds (default: std::chrono::steady_clock), for step start times and
  // overruns; tests replace it together with `sleep`.
  std::function<double()> clock_s;
};

struct CaptureSummary {
  // kWriteFailed: a frame could not be saved (disk full, directory gone or not writable).
  // kDarkFramesLit: dark frames kept showing light (an LED stuck on, room light).
  enum class Status { kComplete, kInterrupted, kCameraFailed, kWriteFailed, kDarkFramesLit };
  Status status = Status::kComplete;
  int frames_captured = 0;  // This run, saved in the session.
  int frames_already_present = 0;
  int camera_retries = 0;
  int frames_reshot = 0;  // Frames shot again because their check failed (SequencerOptions).
  std::string message;    // Why it stopped, for the operator.
  double seconds = 0.0;
  // Time steps completed in this run whose capture took longer than the plan's interval to the
  // next step (also journaled in the session and listed in its manifest).
  std::vector<TimeStepOverrun> overruns;
};

CaptureSummary run_capture(Session& session, LightController& lights, Camera& camera,
                           const SequencerOptions& options);

// Judges the LEDs of every time step whose frames are all saved, as run_capture does when a step
// ends: the signal of an LED whose bracket was split between runs, or whose signal a kill cut
// off, is measured from its saved frames. So a dead LED is flagged whatever moment a capture was
// killed at (run_capture calls it first; a resume that finds nothing missing calls it alone).
void judge_captured_steps(Session& session, double dead_led_threshold);

}  // namespace ls
