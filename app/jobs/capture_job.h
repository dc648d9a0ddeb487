#pragma once
// Capture a session: a stage file and the back-end it names -> a session directory, resumable.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "lightstage/controller/sequencer.h"

namespace ls::jobs {

struct CaptureOptions {
  std::filesystem::path stage_file;  // Empty: the built-in dome.
  std::filesystem::path scene_file;  // The back-end's input file (the simulated stage's scene).
  std::filesystem::path session_dir;
  bool resume = false;  // Complete session_dir (its own stage and back-end) instead of creating it.
  uint64_t seed = 1;    // Noise seed of a simulated camera.
  // Check each frame on arrival and shoot bad ones again (SequencerOptions::verify_frames); off
  // for a camera whose frames do not follow the LEDs (a test pattern, as Aravis' Fake_1 draws).
  bool verify_frames = true;
  // A new session's exposures chosen per LED from this earlier session of the same scene and
  // stage (capture/exposure_choice.h); empty: every LED at the whole bracket.
  std::filesystem::path exposures_from;
  // Empty when the options make sense, else what is wrong, in the CLI's words.
  std::string validate() const;
};

struct CaptureJobSummary {
  bool already_complete = false;  // --resume of a complete session: nothing done.
  int frames_present_before = 0;  // In the session before this run.
  int frames_missing_before = 0;
  FrameCheck frame_check;  // --resume: the saved frames read back; the damaged are re-captured.
  CaptureSummary capture;  // This run (sequencer summary).
  std::vector<std::pair<int, std::string>> dead_leds;  // LED id, why it was flagged.
  std::vector<double> overrun_step_times_s;            // Scene time of each overrun step.
  std::vector<std::string> frame_problems;  // Frames rejected on arrival this run: name, why.
  // The reference LED's drift over each time step captured whole (capture/reference_drift.h),
  // where it exceeds 0.5%.
  std::vector<std::string> drift;
  // With exposures_from: LED frames per time step and their summed exposure, whole bracket
  // against chosen.
  int led_frames_full = 0, led_frames_chosen = 0;
  double exposure_s_full = 0, exposure_s_chosen = 0;
};

struct CaptureCallbacks {
  const std::atomic<bool>* stop_requested = nullptr;  // Set (e.g. by a signal): stop cleanly.
  // Called once the session is open, before any LED turns on.
  std::function<void(const CaptureJobSummary& before, int total_frames)> on_start;
  ProgressFn on_progress;  // As SequencerOptions::on_progress.
};

// Opens the devices of the stage's back-end (ls::backend_registry()) before anything is created or
// resumed, so a missing chip, line or camera stops the job before anything is captured. Throws
// InputError (bad options, stage or scene) and HardwareError (devices).
CaptureJobSummary capture(const CaptureOptions& options, const CaptureCallbacks& callbacks = {});

}  // namespace ls::jobs
