// lightstage play: the dome plays an environment map, and the photograph is checked against the
// field relit under it (the superposition check, app/jobs/play_job.h).
#include <CLI/CLI.hpp>
#include <cstdio>

#include "app/cli/commands.h"
#include "app/cli/validators.h"
#include "app/jobs/play_job.h"

namespace ls::cli {

void add_play_command(CLI::App& app) {
  auto options = std::make_shared<jobs::PlaySessionOptions>();
  auto* cmd = app.add_subcommand(
      "play",
      "Play an environment map on the dome (each LED lit for its share of the map's light), "
      "photograph it, and compare the photograph with the field relit under the same lights: "
      "one check of the LED calibration, the HDR merge and the relighting. When they disagree, "
      "halves of the dome are played in turn down to the LEDs that changed since the capture. "
      "Exit code 3 when they disagree.");
  cmd->add_option("session", options->session_dir, "Session (its stage and back-end are used).")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--field", options->field, "The field built from the session (.exr).")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--env", options->play.env_map, "Environment map (lat-long EXR).")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--rotate", options->play.rotate_deg, "Rotate the map about +Y (degrees).")
      ->capture_default_str()
      ->check(kFinite);
  cmd->add_option("--out", options->play.out_dir,
                  "Folder for photo.exr, relit.exr, compare.png (photograph | relit | "
                  "difference x 8) and report.json.")
      ->required();
  cmd->add_option("--audit-groups", options->play.audit_group_size,
                  "Also play the LEDs in groups of this many neighbours, each fully on, and "
                  "bisect the groups that disagree: finds an LED the map hardly uses (0: off).")
      ->capture_default_str()
      ->check(CLI::Range(0, 1 << 20));
  cmd->add_option("--gain-tolerance", options->play.gain_tolerance,
                  "How much brighter or dimmer than the relit field the photograph may be.")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  add_quiet_flag(*cmd);
  cmd->callback([options] {
    if (std::string problem = jobs::rotation_problem(options->play.rotate_deg); !problem.empty()) {
      throw CLI::ValidationError("play", problem);
    }
    const auto lock = lock_output(options->play.out_dir);
    const jobs::PlayResult r = jobs::play_session(*options);
    std::printf(
        "played %s: PSNR %.1f dB, relative RMSE %.2f%%, brightness %+.2f%%, %d of %d "
        "regions outlying, chi2/N %.2f (%d patterns, %d frames)\n",
        options->play.env_map.filename().c_str(), r.check.psnr_db, 100 * r.check.relative_rmse,
        100 * (r.check.gain - 1), r.check.outlying_blocks, 3 * r.check.blocks, r.check.reduced_chi2,
        r.patterns, r.frames);
    if (r.uncovered_fraction > 0.01) {
      std::printf("note: %.1f%% of the map's light falls where no LED is (not played)\n",
                  100 * r.uncovered_fraction);
    }
    for (const jobs::SuspectLed& s : r.suspects) std::printf("suspect %s\n", s.describe().c_str());
    for (const auto& group : r.unresolved_groups) {
      std::printf("disagreement among LEDs");
      for (const int id : group) std::printf(" %d", id);
      std::printf(" (no smaller group shows it)\n");
    }
    if (r.check.blocks == 0) {
      // Nothing was compared: saying that the dome reproduces the field would be a guess.
      std::printf(
          "%s: nothing checked: the light %s plays reaches no part of the view; play a "
          "map whose light falls on the LEDs that light the scene\n",
          options->play.out_dir.c_str(), options->play.env_map.filename().c_str());
      throw CLI::RuntimeError(kExitInputError);
    }
    const bool found = !r.agrees || !r.suspects.empty() || !r.unresolved_groups.empty();
    std::printf("%s: %s\n", options->play.out_dir.c_str(),
                found ? "the dome does NOT reproduce the field" : "the dome reproduces the field");
    if (found) throw CLI::RuntimeError(kExitHardwareError);
  });
}

}  // namespace ls::cli
