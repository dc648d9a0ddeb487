#pragma once
// Runs a library job from Python: on a thread of its own with the GIL released, while the calling
// thread waits, checks for Ctrl-C (KeyboardInterrupt) and calls the Python progress callable with
// the job's reports, so the callable always runs on the caller's thread. A Ctrl-C or an exception
// raised by the callable stops the job at its next progress report (or, for a capture, before the
// next frame) and is raised once the job has ended.
#include <pybind11/pybind11.h>

#include <atomic>
#include <functional>

#include "lightstage/progress.h"

namespace ls::python {

namespace py = pybind11;

// What a job gets: the progress function to report through (it throws JobStopped once a stop is
// requested) and the stop flag itself (for jobs that poll one, as a capture does).
struct JobContext {
  ProgressFn progress;
  ProgressFn observe;  // The same reports, never throwing: for a job that polls stop_requested.
  const std::atomic<bool>* stop_requested = nullptr;
};

// Thrown inside the job by its progress function once Python asked it to stop.
struct JobStopped {};

// Runs `work` as described above. `progress`: what the user passed (None, True, a callable
// (phase, done, total, item), a tqdm-like class: lightstage/_progress.py).
// Exceptions of the job propagate (as the translators of errors.h map them); a KeyboardInterrupt
// or the callable's own exception takes precedence.
void run_job(const py::object& progress, const std::function<void(const JobContext&)>& work);

}  // namespace ls::python
