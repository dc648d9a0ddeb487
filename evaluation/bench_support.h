#pragma once
// What the benches share: progress reporting, median timings and a simulated capture built into a
// field (the whole pipeline: sequencer, simulated camera frames, HDR merge).
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/progress.h"
#include "lightstage/stage.h"
#include "physics/envmap.h"
#include "sim/scene.h"

namespace ls::evaluation {

// Progress of a bench's phases: the jobs' callback (lightstage/progress.h), so the CLI's printer
// serves both.
using ls::ProgressFn;
using ls::report;

// Median wall time of `repeats` calls of f, in milliseconds.
template <class F>
double median_ms(int repeats, F&& f) {
  std::vector<double> ms;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

// Captures `scene` on the simulated `stage` (camera seed 1) into a session at `session_dir`,
// builds its field and removes the session: the frames are only a means here.
capture::ReflectanceField capture_sim_field(const Stage& stage, const sim::Scene& scene,
                                            const std::filesystem::path& session_dir,
                                            const std::string& phase, const ProgressFn& progress);

// A step run as the user runs it: its own process.
struct Measured {
  double seconds = 0;
  double peak_mib = 0;  // The process's own peak resident memory (wait4's ru_maxrss).
  std::string output;   // What it printed.
};

// Runs `argv` (argv[0] looked up on PATH when it has no '/'), its output written to `log`;
// InputError naming the command and the log when it fails.
Measured run_process(const std::vector<std::string>& argv, const std::filesystem::path& log);

std::vector<physics::EnvironmentMap> load_maps(const std::vector<std::filesystem::path>& paths);

// Throws InputError with `error` unless it is empty (the options' validate()).
void throw_if_invalid(const std::string& error);

}  // namespace ls::evaluation
