// lightstage build: session -> reflectance field (OpenEXR).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>

#include "capture/build_field.h"
#include "app/cli/commands.h"
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
  if (!summary.flat_field.empty()) {
    std::fprintf(stderr, "flat field applied to %d LEDs: %s\n", summary.flat_field_lights,
                 summary.flat_field.c_str());
  }
  if (summary.near_lights > 0) {
    std::fprintf(stderr,
                 "%d near LEDs: per-pixel distance and direction (reference plane z = %g m)\n",
                 summary.near_lights, session.stage().calibration.reference_z_m);
  }
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

namespace {

// One field per time step: DIR/field_t000.exr, ... (each stores its scene time, capture/field.h).
int build_all_time_steps(const std::filesystem::path& session_dir,
                         const std::filesystem::path& out_dir, bool quiet) {
  const Session session = Session::open(session_dir);
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec || !std::filesystem::is_directory(out_dir)) {
    throw InputError(out_dir.string() + ": --out: expected a directory for --all-time-steps (" +
                     (ec ? ec.message() : std::string("not a directory")) + ")");
  }
  const CapturePlan& plan = session.stage().plan;
  for (int t = 0; t < plan.time_steps; ++t) {
    char name[32];
    std::snprintf(name, sizeof name, "field_t%03d.exr", t);
    if (!quiet) {
      std::fprintf(stderr, "time step %d of %d (scene time %g s)\n", t + 1, plan.time_steps,
                   plan.step_time_s(t));
    }
    build_field_file(session_dir, out_dir / name, t, quiet);
  }
  return 0;
}

}  // namespace

void add_build_command(CLI::App& app) {
  struct Args {
    std::filesystem::path session, out;
    int time_step = 0;
    bool all_time_steps = false;
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
  cmd->add_option("--out", args->out,
                  "Field file to write (.exr); with --all-time-steps, the directory to write "
                  "field_t000.exr, field_t001.exr, ... into.")
      ->required();
  auto* step =
      cmd->add_option("--time-step", args->time_step, "Time step to build (time-varying sessions).")
          ->capture_default_str();
  cmd->add_flag("--all-time-steps", args->all_time_steps,
                "Build one field per time step into the --out directory.")
      ->excludes(step);
  cmd->add_flag("--quiet", args->quiet, "No progress output.");
  cmd->callback([args] {
    if (args->all_time_steps) {
      build_all_time_steps(args->session, args->out, args->quiet);
    } else {
      build_field_file(args->session, args->out, args->time_step, args->quiet);
    }
  });
}

}  // namespace ls::cli
