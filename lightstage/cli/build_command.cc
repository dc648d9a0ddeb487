// lightstage build: session -> reflectance field (OpenEXR).
#include <CLI/CLI.hpp>
#include <cstdio>

#include "capture/build_field.h"
#include "lightstage/cli/commands.h"
#include "lightstage/errors.h"
#include "lightstage/progress.h"

namespace ls::cli {

int build_field_file(const std::filesystem::path& session_dir, const std::filesystem::path& out,
                     int time_step, bool quiet) {
  const Session session = Session::open(session_dir);
  if (time_step < 0 || time_step >= session.stage().plan.time_steps) {
    throw InputError(session_dir.string() + ": --time-step " + std::to_string(time_step) +
                     " is outside the session's 0.." +
                     std::to_string(session.stage().plan.time_steps - 1));
  }
  ProgressReporter progress("build", long(session.stage().leds.size()), quiet);
  capture::BuildOptions options;
  options.time_step = time_step;
  options.on_progress = [&](int done, int) { progress.update(done); };
  capture::BuildSummary summary;
  const capture::ReflectanceField field = capture::build_field(session, options, &summary);
  progress.done();
  capture::write_field(out, field);
  std::fprintf(stderr,
               "%s: %dx%d pixels x %d LEDs (%.1f MiB), response %s, %.3f%% samples saturated in "
               "every exposure, %.1f s\n",
               out.c_str(), field.width(), field.height(), field.num_lights(),
               field.bytes() / 1048576.0, summary.response_used.c_str(),
               100.0 * summary.saturated_fraction, summary.seconds);
  for (const auto& warning : summary.warnings)
    std::fprintf(stderr, "warning: %s\n", warning.c_str());
  if (!summary.lights_missing.empty()) {
    std::fprintf(stderr, "warning: %zu LEDs missing or dead, excluded from relighting:",
                 summary.lights_missing.size());
    for (int i : summary.lights_missing) std::fprintf(stderr, " %d", session.stage().leds[i].id);
    std::fprintf(stderr, "\n");
  }
  return 0;
}

void add_build_command(CLI::App& app) {
  struct Args {
    std::filesystem::path session, out;
    int time_step = 0;
    bool quiet = false;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand(
      "build",
      "Build the reflectance field of a session: dark subtraction, HDR merge through the camera "
      "response, division by each LED's calibrated irradiance and colour. Writes an OpenEXR with "
      "one channel per LED and colour (led042.R, ...).");
  cmd->add_option("session", args->session, "Session directory.")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", args->out, "Field file to write (.exr).")->required();
  cmd->add_option("--time-step", args->time_step, "Time step to build (time-varying sessions).")
      ->capture_default_str();
  cmd->add_flag("--quiet", args->quiet, "No progress output.");
  cmd->callback(
      [args] { build_field_file(args->session, args->out, args->time_step, args->quiet); });
}

}  // namespace ls::cli
