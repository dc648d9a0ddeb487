#pragma once
// Progress for long work, on stderr: a live bar on a terminal ("capture [#####     ] 120/453
// 26% 0:14 left"), a line per 10% otherwise (logs, CI). Thread-safe; at most ~10 updates a second.
#include <chrono>
#include <functional>
#include <mutex>
#include <string>
#include <utility>

namespace ls {

// Progress of one phase of a long job ("build", "fit (rows)", ...): `done` of `total` units, the
// item just finished. done == total ends the phase. The CLI prints it with a ProgressReporter.
using ProgressFn =
    std::function<void(const std::string& phase, long done, long total, const std::string& item)>;

inline void report(const ProgressFn& progress, const std::string& phase, long done, long total,
                   const std::string& item = {}) {
  if (progress) progress(phase, done, total, item);
}

// Units of one phase finished by several threads: each finish counted and reported under one lock,
// so the reports arrive in order (a worker that finished unit 39 cannot report after the one that
// finished the 40th and ended the phase).
class ProgressCount {
 public:
  ProgressCount(const ProgressFn& progress, std::string phase, long total)
      : progress_(progress), phase_(std::move(phase)), total_(total) {}
  void finished_one(const std::string& item = {}) {
    const std::lock_guard lock(mutex_);
    report(progress_, phase_, ++done_, total_, item);
  }

 private:
  const ProgressFn& progress_;
  std::string phase_;
  long total_;
  long done_ = 0;
  std::mutex mutex_;
};

// How long a job's phases took.
using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

class ProgressReporter {
 public:
  ProgressReporter(std::string title, long total, bool quiet = false);
  ~ProgressReporter();  // Finishes the line.
  void update(long done, const std::string& detail = "");
  void done(const std::string& summary = "");

 private:
  void print(long done, const std::string& detail, bool final);
  std::string title_;
  long total_;
  bool quiet_;
  bool tty_;
  bool finished_ = false;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_, last_print_;
  std::mutex mutex_;
};

}  // namespace ls
