#pragma once
// What every job shares: progress reporting and the record of the options used.
#include <chrono>
#include <functional>
#include <string>

namespace ls::jobs {

// Progress of one phase of a job ("build", "relight", ...): `done` of `total` units, the item just
// finished. done == total ends the phase. The CLI prints it (lightstage/progress.h).
using ProgressFn =
    std::function<void(const std::string& phase, long done, long total, const std::string& item)>;

inline void report(const ProgressFn& progress, const std::string& phase, long done, long total,
                   const std::string& item = {}) {
  if (progress) progress(phase, done, total, item);
}

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// EXR header attribute that records the options a job ran with (JSON), so every output says how
// it was made.
inline constexpr const char* kOptionsAttribute = "lightstage:options";

}  // namespace ls::jobs
