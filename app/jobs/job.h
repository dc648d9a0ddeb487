#pragma once
// What every job shares: progress reporting and the record of the options used.
#include "lightstage/progress.h"

namespace ls::jobs {

// Every job reports progress by phases and times them (lightstage/progress.h).
using ls::Clock;
using ls::ProgressFn;
using ls::report;
using ls::seconds_since;

// EXR header attribute that records the options a job ran with (JSON), so every output says how
// it was made.
inline constexpr const char* kOptionsAttribute = "lightstage:options";

}  // namespace ls::jobs
