#include "lightstage/controller/frame_writer.h"

#include <utility>
#include <vector>

namespace ls {

FrameWriter::FrameWriter(Session& session, std::size_t max_queued_bytes,
                         std::size_t max_queued_frames)
    : session_(session),
      max_queued_bytes_(max_queued_bytes),
      max_queued_frames_(max_queued_frames),
      thread_([this] { run(); }) {}

FrameWriter::~FrameWriter() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void FrameWriter::throw_if_failed_locked() const {
  if (error_) std::rethrow_exception(error_);
}

void FrameWriter::enqueue(Job job, std::size_t bytes) {
  const bool is_frame = std::holds_alternative<FrameJob>(job);
  std::unique_lock lock(mutex_);
  throw_if_failed_locked();
  // Backpressure: wait for room, but always admit one job into an empty queue.
  changed_.wait(lock, [&] {
    return error_ || queued_bytes_ == 0 ||
           (queued_bytes_ + bytes <= max_queued_bytes_ &&
            (!is_frame || queued_frames_ < max_queued_frames_));
  });
  throw_if_failed_locked();
  queue_.emplace_back(std::move(job), bytes);
  queued_bytes_ += bytes;
  queued_frames_ += is_frame;
  lock.unlock();
  changed_.notify_all();
}

void FrameWriter::write(const PlannedFrame& planned, CapturedFrame frame) {
  const std::size_t bytes = frame.raw.pixels.size() * sizeof(uint16_t) + 1024;
  enqueue(FrameJob{planned, std::move(frame)}, bytes);
}

void FrameWriter::record_led_signal(int time_step, int led_index, double fraction) {
  enqueue(SignalJob{time_step, led_index, fraction}, 64);
}

void FrameWriter::mark_dead_led(int led_index, const std::string& reason) {
  enqueue(DeadLedJob{led_index, reason}, 64 + reason.size());
}

void FrameWriter::record_frame_problem(const FrameProblem& problem) {
  enqueue(problem, 64 + problem.problem.size());
}

void FrameWriter::flush() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [&] { return queue_.empty() && !busy_; });
  throw_if_failed_locked();
}

void FrameWriter::run() {
  for (;;) {
    std::deque<std::pair<Job, std::size_t>> batch;
    bool failed = false;
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] { return !queue_.empty() || stopping_; });
      if (queue_.empty()) return;  // Stopping, and nothing left to write.
      batch.swap(queue_);
      busy_ = true;
      failed = error_ != nullptr;
    }
    std::exception_ptr error;
    std::vector<FrameRecord> written;  // Files written and not yet journaled.
    if (!failed) {  // After a failure nothing more is written: the rest is re-captured on resume.
      try {
        // Frame files first, then one journal append for the run of frames; the other jobs keep
        // their place in the journal's order.
        for (auto& [job, bytes] : batch) {
          if (auto* frame = std::get_if<FrameJob>(&job)) {
            written.push_back(session_.write_frame_file(frame->planned, frame->frame));
            continue;
          }
          session_.journal_frames(written);
          written.clear();
          if (auto* signal = std::get_if<SignalJob>(&job)) {
            session_.record_led_signal(signal->time_step, signal->led_index, signal->fraction);
          } else if (auto* dead = std::get_if<DeadLedJob>(&job)) {
            session_.mark_dead_led(dead->led_index, dead->reason);
          } else if (auto* problem = std::get_if<FrameProblem>(&job)) {
            session_.record_frame_problem(*problem);
          }
        }
        session_.journal_frames(written);
      } catch (...) {
        error = std::current_exception();
        try {
          session_.journal_frames(written);  // Keep the frames that did reach the disk.
        } catch (...) {
        }
      }
    }
    {
      std::lock_guard lock(mutex_);
      for (const auto& [job, bytes] : batch) {
        queued_bytes_ -= bytes;
        queued_frames_ -= std::holds_alternative<FrameJob>(job);
      }
      if (error && !error_) error_ = error;
      busy_ = false;
    }
    changed_.notify_all();
  }
}

}  // namespace ls
