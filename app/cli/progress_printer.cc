#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "app/cli/commands.h"
#include "lightstage/progress.h"

namespace ls::cli {

jobs::ProgressFn progress_printer(bool quiet) {
  struct State {
    std::mutex mutex;  // Jobs report from worker threads.
    std::string phase;
    std::optional<ProgressReporter> bar;
  };
  auto state = std::make_shared<State>();
  return [state, quiet](const std::string& phase, long done, long total, const std::string& item) {
    std::lock_guard lock(state->mutex);
    if (!state->bar || state->phase != phase) {
      state->bar.reset();  // Finishes the previous phase's line first.
      state->bar.emplace(phase, total, quiet);
      state->phase = phase;
    }
    if (done >= total) {
      state->bar->done();
      state->bar.reset();
      state->phase.clear();
    } else {
      state->bar->update(done, item);
    }
  };
}

void add_quiet_flag(CLI::App& cmd, bool& quiet) {
  cmd.add_flag("--quiet", quiet, "No progress output.");
}

void add_quiet_flag(CLI::App& cmd) {
  static const std::string kHelp = "No progress output (this command shows none).";
  cmd.add_flag("--quiet", kHelp);
}

std::string storage_line(const capture::FieldStorage& storage,
                         const std::optional<capture::HalfCheck>& half_check,
                         double file_mebibytes) {
  char size[64];
  std::snprintf(size, sizeof size, "%.1f MiB on disk", file_mebibytes);
  if (!half_check) return std::string("stored in floats (--storage float): ") + size;
  if (storage.half) {
    char scale[48];
    std::snprintf(scale, sizeof scale, " (x%g)", double(storage.scale));
    return std::string("stored in half floats") + scale + ": " + size + "; " +
           half_check->describe();
  }
  return std::string("stored in floats: ") + size + "; half would give " + half_check->describe();
}

}  // namespace ls::cli
