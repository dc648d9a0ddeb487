#include "python/src/runner.h"

#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>

namespace ls::python {

namespace {

struct Report {
  std::string phase, item;
  long done = 0, total = 0;
};

// What the job's threads and the waiting Python thread share.
class Channel {
 public:
  // From the job's threads: queues a report, unless a stop was requested (then throws JobStopped).
  void report(const std::string& phase, long done, long total, const std::string& item,
              bool may_stop) {
    if (may_stop && stop_.load(std::memory_order_relaxed)) throw JobStopped{};
    if (!forward_) return;
    std::lock_guard lock(mutex_);
    // Only the newest report of a phase waits: a slow callable sees fewer, never stale, updates.
    const bool replace =
        !queue_.empty() && queue_.back().phase == phase && queue_.back().done < queue_.back().total;
    if (replace) {
      queue_.back() = Report{phase, item, done, total};
    } else {
      queue_.push_back(Report{phase, item, done, total});
    }
    wake_.notify_one();
  }
  void finish() {
    std::lock_guard lock(mutex_);
    finished_ = true;
    wake_.notify_one();
  }
  // Waits up to `timeout` for reports or the end; returns the reports and whether the job ended.
  std::pair<std::deque<Report>, bool> wait(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    wake_.wait_for(lock, timeout, [&] { return finished_ || !queue_.empty(); });
    return {std::exchange(queue_, {}), finished_};
  }
  void request_stop() { stop_ = true; }
  const std::atomic<bool>* stop_flag() const { return &stop_; }
  void set_forward(bool forward) { forward_ = forward; }

 private:
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Report> queue_;
  bool finished_ = false;
  bool forward_ = false;
  std::atomic<bool> stop_{false};
};

// Calls the progress callable with each report; checks for Ctrl-C. Holds the GIL. Returns the
// Python error that asks the job to stop, if any.
std::optional<py::error_already_set> deliver(const py::object& progress,
                                             const std::deque<Report>& reports) {
  if (PyErr_CheckSignals() != 0) return py::error_already_set();
  if (progress.is_none()) return std::nullopt;
  try {
    for (const Report& r : reports) progress(r.phase, r.done, r.total, r.item);
  } catch (py::error_already_set& e) {
    return std::move(e);
  }
  return std::nullopt;
}

}  // namespace

void run_job(const py::object& what_user_passed,
             const std::function<void(const JobContext&)>& work) {
  const py::object progress =
      py::module_::import("lightstage._progress").attr("adapt")(what_user_passed);
  Channel channel;
  channel.set_forward(!progress.is_none());
  JobContext context;
  context.progress = [&channel](const std::string& phase, long done, long total,
                                const std::string& item) {
    channel.report(phase, done, total, item, /*may_stop=*/true);
  };
  context.observe = [&channel](const std::string& phase, long done, long total,
                               const std::string& item) {
    channel.report(phase, done, total, item, /*may_stop=*/false);
  };
  context.stop_requested = channel.stop_flag();

  std::exception_ptr job_error;
  std::optional<py::error_already_set> python_error;
  {
    py::gil_scoped_release release;
    std::thread job([&] {
      try {
        work(context);
      } catch (const JobStopped&) {
        // Python's error (below) says why.
      } catch (...) {
        job_error = std::current_exception();
      }
      channel.finish();
    });
    for (bool finished = false; !finished;) {
      // Ctrl-C is seen within this period even when the job reports nothing.
      auto [reports, ended] = channel.wait(std::chrono::milliseconds(50));
      finished = ended;
      py::gil_scoped_acquire acquire;
      if (python_error) continue;  // Stopping: the job's last reports are not shown.
      python_error = deliver(progress, reports);
      if (python_error) channel.request_stop();
    }
    job.join();
  }
  if (python_error) throw std::move(*python_error);
  if (job_error) std::rethrow_exception(job_error);
}

}  // namespace ls::python
