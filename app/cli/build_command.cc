// lightstage build: session -> reflectance field (OpenEXR).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>

#include "app/cli/commands.h"
#include "app/jobs/ranks.h"
#include "lightstage/memory.h"
#include "lightstage/memory_option.h"

namespace ls::cli {

int build_field_file(const jobs::BuildJobOptions& options, bool quiet) {
  // Under MPI rank 0 reports (its own share of the LEDs, then the writing) and prints.
  const bool root = jobs::Ranks::world().root();
  const auto lock = lock_output(options.out);
  const jobs::BuildJobSummary summary = jobs::build(options, progress_printer(quiet || !root));
  if (!root) return 0;
  const bool several = summary.fields.size() > 1;
  for (const jobs::BuiltField& built : summary.fields) {
    const capture::BuildSummary& s = built.build;
    if (several && !quiet) {
      std::fprintf(stderr, "time step %d of %zu (scene time %g s)\n", built.time_step + 1,
                   summary.fields.size(), built.scene_time_s);
    }
    std::fprintf(stderr,
                 "%s: %dx%d pixels x %d LEDs (%.1f MiB as floats), response %s, %.3f%% samples "
                 "saturated in every exposure, %.1f s\n",
                 built.file.c_str(), built.width, built.height, built.lights, built.mebibytes,
                 s.response_used.c_str(), 100.0 * s.saturated_fraction, s.seconds);
    std::fprintf(stderr, "%s\n",
                 storage_line(s.storage, s.half_check, built.file_mebibytes).c_str());
    if (built.band_rows < built.height || built.ranks > 1) {
      std::fprintf(stderr, "built in bands of %d rows through a spill file beside it",
                   built.band_rows);
      if (built.ranks > 1) std::fprintf(stderr, ", LEDs merged by %d MPI ranks", built.ranks);
      if (s.resumed_lights > 0) {
        std::fprintf(stderr, " (%d LEDs' merges taken from an interrupted run)", s.resumed_lights);
      }
      std::fprintf(stderr, "\n");
    }
    if (!s.flat_field.empty()) {
      std::fprintf(stderr, "flat field applied to %d LEDs: %s\n", s.flat_field_lights,
                   s.flat_field.c_str());
    }
    if (s.near_lights > 0) {
      std::fprintf(stderr,
                   "%d near LEDs: per-pixel distance and direction (reference plane z = %g m)\n",
                   s.near_lights, summary.reference_z_m);
    }
    for (const auto& warning : s.warnings) std::fprintf(stderr, "warning: %s\n", warning.c_str());
    if (!built.missing_led_ids.empty()) {
      std::fprintf(stderr, "warning: %zu LEDs missing or dead, excluded from relighting:",
                   built.missing_led_ids.size());
      for (int id : built.missing_led_ids) std::fprintf(stderr, " %d", id);
      std::fprintf(stderr, "\n");
    }
  }
  return 0;
}

void add_build_command(CLI::App& app) {
  auto options = std::make_shared<jobs::BuildJobOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand(
      "build",
      "Build the reflectance field of a session: dark subtraction, HDR merge through the camera "
      "response, division by each LED's calibrated irradiance and colour. Writes an OpenEXR with "
      "one channel per LED and colour (led042.R, ...).");
  cmd->add_option("session", options->session_dir, "Session directory.")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", options->out,
                  "Field file to write (.exr); with --all-time-steps, the directory to write "
                  "field_t000.exr, field_t001.exr, ... into.")
      ->required();
  auto* step = cmd->add_option("--time-step", options->time_step,
                               "Time step to build (time-varying sessions).")
                   ->capture_default_str();
  cmd->add_flag("--all-time-steps", options->all_time_steps,
                "Build one field per time step into the --out directory.")
      ->excludes(step);
  add_memory_option(*cmd, options->memory,
                    "Build: the field's values and the LEDs merged in flight (a quarter of it); a "
                    "larger field is built in bands, each LED's image spilled to a file beside "
                    "--out that needs the field's size free.");
  cmd->add_option("--storage", options->storage,
                  "How the file holds the values: half floats (half the disk and the reading) "
                  "where the field relit from them stays within 1e-3 of the floats and their "
                  "rounding within 0.25 sigma of the field's measured noise, else floats (auto); "
                  "or always half or float. Recorded in the file (lightstage:storage).")
      ->check(CLI::IsMember({"auto", "half", "float"}))
      ->capture_default_str();
  cmd->add_flag("--correct-drift", options->correct_drift,
                "Divide each LED's image by the dome's output drift while it was shot, measured "
                "on the stage plan's reference LED (plan.reference_led, shot again every "
                "plan.reference_every LEDs). Drift beyond 0.5% is reported either way.");
  add_quiet_flag(*cmd, *quiet);
  cmd->callback([options, quiet] {
    if (const std::string problem = options->validate(); !problem.empty()) {
      throw CLI::ValidationError("build", problem);
    }
    build_field_file(*options, *quiet);
    if (jobs::Ranks::world().root()) {
      std::printf("peak memory %.1f MiB\n", double(peak_resident_bytes()) / (1 << 20));
    }
  });
}

}  // namespace ls::cli
