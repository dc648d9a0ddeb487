#pragma once
// A capture session on disk:
//   SESSION/manifest.json   stage, back-end, seed, plan, status (rewritten atomically)
//   SESSION/frames.jsonl    journal: one line per frame, appended (and fsync'ed) after the frame's
//                           image is durably renamed into place; a torn last line is ignored
//   SESSION/frames/*.png    16-bit frames, each written to a temporary name then renamed
//   SESSION/originals/*     the camera's own files where it writes them (a DSLR's raw files)
// What is missing is always "the plan minus the journal", so a killed capture resumes exactly.
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "lightstage/hardware.h"
#include "lightstage/output_lock.h"
#include "lightstage/stage.h"

namespace ls {

// Identity of one frame in the plan. led_index < 0 marks a dark frame (all LEDs off).
struct FrameKey {
  int time_step = 0;
  int led_index = -1;
  int exposure_index = 0;
  // Dark frames are repeated; lit frames have repeat 0, but the reference LED's drift shots
  // (CapturePlan::reference_led), repeats 1, 2, ...
  int repeat = 0;

  bool is_dark() const { return led_index < 0; }
  // e.g. "t000_led042_e1", "t000_led042_e1_ref2" or "t000_dark_e1_r0"
  std::string name(const Stage& stage) const;
  auto operator<=>(const FrameKey&) const = default;
};

struct PlannedFrame {
  FrameKey key;
  FrameRequest request;
};

// The whole plan in capture order: per time step, the dark frames, then each LED's bracket.
std::vector<PlannedFrame> plan_frames(const Stage& stage);

struct FrameRecord {
  FrameKey key;
  std::string file;         // Relative to the session directory.
  double exposure_s = 0.0;  // As reported by the camera.
  double gain = 1.0;
  double scene_time_s = 0.0;
  std::string captured_at;  // ISO 8601 UTC.
  // The file as written (absent in older journals: bytes = 0).
  uint64_t bytes = 0;
  uint32_t crc32 = 0;
  FrameTiming timing;  // Journaled as "timing" (absent in older journals: all 0).
  // The camera's own file (a DSLR's raw), kept as written: SESSION/originals/<frame><.ext>.
  // Journaled as "original" {"file", "bytes", "crc32"}; empty when the camera delivered pixels.
  std::string original_file;
  StoredFile original;
};

// What Session::verify_frames found: frames whose files are not what was saved.
struct FrameCheck {
  int verified = 0;  // Frames whose files are as saved.
  uint64_t bytes_read = 0;
  std::vector<std::string> damaged;  // One line per damaged frame: its file and what is wrong.
};

// A time step whose capture took longer than the time to the next step (CapturePlan).
struct TimeStepOverrun {
  int time_step = 0;
  double capture_s = 0.0;   // Wall-clock time from its first frame to its last, this run.
  double interval_s = 0.0;  // What the plan allowed: CapturePlan::step_interval_s.
};

// A frame that failed its check on arrival (controller/frame_checks.h) and was shot again.
struct FrameProblem {
  FrameKey key;
  int attempt = 0;  // 0 for the first shot.
  std::string problem;
};

struct SessionInfo {
  std::string backend = "sim";
  std::string scene_file;  // Simulated stage only.
  uint64_t seed = 1;
  // The camera's settings as it reported them once set (a DSLR's shutter, ISO, aperture, format):
  // manifest "camera_settings".
  std::vector<std::pair<std::string, std::string>> camera_settings;
};

// One capture writes a session at a time: an exclusive lock on SESSION/capture.lock (a
// WriterLock), held while this lives. InputError naming the holding process when another capture
// holds it.
class SessionWriterLock {
 public:
  explicit SessionWriterLock(const std::filesystem::path& session_dir);

  // The process of a capture writing the session now, if one is.
  static std::optional<pid_t> capturing(const std::filesystem::path& session_dir);

 private:
  WriterLock lock_;
};

class Session {
 public:
  // Creates SESSION; refuses a directory that already holds a session (use open + resume).
  static Session create(const std::filesystem::path& dir, const Stage& stage,
                        const SessionInfo& info);
  // Opens an existing session; throws InputError naming the file if it is not one.
  static Session open(const std::filesystem::path& dir);

  const std::filesystem::path& dir() const { return dir_; }
  const Stage& stage() const { return stage_; }
  const SessionInfo& info() const { return info_; }
  const std::map<FrameKey, FrameRecord>& frames() const { return frames_; }
  std::vector<PlannedFrame> missing_frames() const;
  bool complete() const { return missing_frames().empty(); }

  // Writes the frame atomically, then journals it. After this returns the frame survives kill -9.
  void record_frame(const PlannedFrame& planned, const CapturedFrame& frame);
  // The two halves of record_frame, for writing on another thread (FrameWriter):
  // write_frame_file touches only the frame's own file (fsync'ed, renamed into place) and may run
  // concurrently with anything; journal_frames appends the records in one fsync'ed write and makes
  // them frames of the session. A frame whose file is written but not journaled is not a frame: a
  // resume captures it again.
  FrameRecord write_frame_file(const PlannedFrame& planned, const CapturedFrame& frame) const;
  void journal_frames(const std::vector<FrameRecord>& records);
  RawFrame load_frame(const FrameKey& key) const;  // Throws InputError if absent or unreadable.
  // Reads every journaled frame's file back and checks it against the journal (size and CRC-32;
  // for frames journaled without them, that it decodes at the stage camera's size). Damaged
  // frames stop being frames of the session, so that a resume captures them again.
  FrameCheck verify_frames();

  // LEDs judged broken (see sequencer.h); later stages treat them as missing, not as black lights.
  const std::map<int, std::string>& dead_leds() const { return dead_leds_; }
  void mark_dead_led(int led_index, const std::string& reason);

  // Each LED's brightest signal above the dark frame (fraction of full scale) per time step,
  // journaled so that the dead-LED judgement survives an interrupted capture.
  const std::map<std::pair<int, int>, double>& led_signals() const { return led_signals_; }
  void record_led_signal(int time_step, int led_index, double fraction_of_full_scale);

  // Time steps that overran their interval, journaled and listed in the manifest
  // ("time_step_overruns"); a step overrunning again on resume replaces its entry.
  const std::map<int, TimeStepOverrun>& time_step_overruns() const { return overruns_; }
  void record_time_step_overrun(const TimeStepOverrun& overrun);

  // Frames rejected on arrival, journaled and listed in the manifest ("frame_problems"), in order.
  const std::vector<FrameProblem>& frame_problems() const { return frame_problems_; }
  void record_frame_problem(const FrameProblem& problem);

  // Rewrites the manifest with the given status ("capturing", "interrupted", "complete", ...).
  void write_manifest(const std::string& status) const;

 private:
  Session() = default;
  void append_journal(const std::string& lines) const;  // One or more '\n'-ended lines.

  std::filesystem::path dir_;
  Stage stage_;
  SessionInfo info_;
  std::map<FrameKey, FrameRecord> frames_;
  std::map<int, std::string> dead_leds_;
  std::map<std::pair<int, int>, double> led_signals_;  // (time step, LED index) -> signal.
  std::map<int, TimeStepOverrun> overruns_;            // By time step.
  std::vector<FrameProblem> frame_problems_;
};

}  // namespace ls
