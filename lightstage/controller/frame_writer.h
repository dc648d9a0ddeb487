#pragma once
// Saves captured frames on a thread of its own, so that the camera never waits on the disk.
//
// Why: encoding a frame and making it durable (fsync of the file, its directory and the journal)
// costs about as much as a short exposure; done inline it is dead time between exposures. Here the
// sequencer hands a frame over and goes on; the writer writes each frame's file durably, then
// journals all frames written so far in one fsync'ed append (group commit). The journal stays the
// only record of what was captured, so a frame still in the queue when the process dies is simply
// not a frame: a resume captures it again. What it costs is bounded by max_queued_bytes and
// max_queued_frames, and so is the time a stop waits for the queue to drain: the count bounds it
// for small frames, whose cost is the fsyncs, not the bytes.
//
// While a FrameWriter is active the session is changed only through it (frames, LED signals, dead
// LEDs, all journaled in submission order); call flush() before reading the session.
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <variant>

#include "lightstage/session.h"

namespace ls {

class FrameWriter {
 public:
  explicit FrameWriter(Session& session, std::size_t max_queued_bytes = std::size_t(256) << 20,
                       std::size_t max_queued_frames = 64);
  // Finishes writing what is queued (errors are dropped: call flush() to see them).
  ~FrameWriter();
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  // Queue for writing. Blocks while the queue is full. Throws the writer's first error (e.g. the
  // disk is full), after which nothing more is written.
  void write(const PlannedFrame& planned, CapturedFrame frame);
  void record_led_signal(int time_step, int led_index, double fraction_of_full_scale);
  void mark_dead_led(int led_index, const std::string& reason);
  void record_frame_problem(const FrameProblem& problem);

  // Waits until everything queued is in the session; throws the writer's first error.
  void flush();

 private:
  struct FrameJob {
    PlannedFrame planned;
    CapturedFrame frame;
  };
  struct SignalJob {
    int time_step, led_index;
    double fraction;
  };
  struct DeadLedJob {
    int led_index;
    std::string reason;
  };
  using Job = std::variant<FrameJob, SignalJob, DeadLedJob, FrameProblem>;

  void enqueue(Job job, std::size_t bytes);
  void run();
  void throw_if_failed_locked() const;

  Session& session_;
  const std::size_t max_queued_bytes_;
  const std::size_t max_queued_frames_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::pair<Job, std::size_t>> queue_;  // With each job's bytes.
  std::size_t queued_bytes_ = 0;
  std::size_t queued_frames_ = 0;  // Frame jobs in queue_.
  bool busy_ = false;              // The writer thread holds jobs taken off the queue.
  bool stopping_ = false;
  std::exception_ptr error_;
  std::thread thread_;  // Last: starts after everything above is initialised.
};

}  // namespace ls
