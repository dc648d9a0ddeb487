// lightstage relight: field (or fitted model maps, optionally edited) + environment maps -> relit
// images (EXR + PNG previews + contact sheet).
#include <CLI/CLI.hpp>
#include <cstdio>

#include "app/cli/commands.h"
#include "app/jobs/ranks.h"
#include "app/jobs/relight_job.h"
#include "lightstage/memory.h"
#include "lightstage/memory_option.h"
#include "relight/time/temporal_fit.h"

namespace ls::cli {

namespace fs = std::filesystem;

jobs::RelightSummary relight_and_report(const jobs::RelightOptions& options, bool quiet) {
  // Under MPI rank 0 reports and prints; the others are silent.
  const bool root = jobs::Ranks::world().root();
  const auto lock = lock_output(options.out_dir);
  jobs::RelightSummary summary = jobs::relight(options, progress_printer(quiet || !root));
  if (!root) return summary;
  if (!quiet) {
    for (const std::string& line : summary.edit_reports)
      std::fprintf(stderr, "  %s\n", line.c_str());
    for (const jobs::RelitImage& image : summary.images) {
      if (!image.detail.empty()) {
        std::fprintf(stderr, "  %s: %s\n", image.label.c_str(), image.detail.c_str());
      }
    }
  }
  std::printf("%zu images in %s; peak memory %.1f MiB\n", summary.images.size(),
              options.out_dir.c_str(), double(peak_resident_bytes()) / (1 << 20));
  if (summary.field_pass_s > 0) {
    std::printf("field read and relit in %.3f s (%.0f MiB/s of its file)", summary.field_pass_s,
                summary.field_file_bytes / (1 << 20) / summary.field_pass_s);
    if (summary.ranks > 1) std::printf(", its bands split over %d MPI ranks", summary.ranks);
    std::printf("\n");
  }
  if (!options.temporal_file.empty()) {
    const int extrapolated = summary.extrapolated_pixels;
    std::printf("t = %.1f s (captured %.1f .. %.1f s)%s\n", *options.time_s, summary.first_time_s,
                summary.last_time_s,
                extrapolated > 0 ? ": EXTRAPOLATED beyond the captured steps" : "");
    if (extrapolated > 0) {
      std::printf("  %d varying pixels extrapolated (flag %d in their model maps)\n", extrapolated,
                  relight::kExtrapolated);
    }
  }
  return summary;
}

void add_relight_command(CLI::App& app) {
  auto options = std::make_shared<jobs::RelightOptions>();
  auto quiet = std::make_shared<bool>(false);
  // CLI11 binds plain values: these become the options' optionals when given.
  auto exposure = std::make_shared<double>(0.0);
  auto light = std::make_shared<std::vector<double>>();
  auto time_s = std::make_shared<double>(0.0);
  auto* cmd = app.add_subcommand(
      "relight",
      "Relight a reflectance field under lat-long HDR environment maps (.exr, .hdr): each LED "
      "stands for its spherical Voronoi cell of directions, I = sum_l R_l E_l. Or, with --models, "
      "render the per-pixel BRDF models of 'lightstage fit' (edited with --edits) under the maps. "
      "Writes NAME.exr (linear) and NAME.png (tone-mapped preview) per map and rotation, and "
      "contact_sheet.png.");
  cmd->add_option("field", options->field_file,
                  "Reflectance field (.exr from 'lightstage build'); optional with --models.")
      ->check(CLI::ExistingFile);
  cmd->add_option("--models", options->models_file,
                  "Render fitted model maps (.exr from 'lightstage fit') instead of the field. "
                  "The models have no shadows; pixels the fit flagged are black. With a field "
                  "too, flagged pixels come from the field relit under the same map, and the "
                  "models get only the light the dome covers, as the field does.")
      ->check(CLI::ExistingFile);
  cmd->add_option("--edits", options->edits_file,
                  "Edit file (JSON: selections by model or mask, albedo tint, roughness / "
                  "specular / sigma scales, model swaps) applied to --models before rendering.")
      ->check(CLI::ExistingFile);
  cmd->add_option("--directions", options->directions_width,
                  "With --models: the map is integrated on a lat-long grid of N x N/2 directions.")
      ->check(CLI::Range(4, 4096))
      ->capture_default_str();
  cmd->add_option("--env", options->maps, "Environment map(s), lat-long .exr or .hdr.")
      ->check(CLI::ExistingFile);
  cmd->add_option("--light", *light,
                  "With --models: also render under one distant light from direction X Y Z "
                  "(stage frame, toward the light) of unit irradiance, as light.exr/png.")
      ->expected(3);
  cmd->add_option("--rotate", options->rotations_deg,
                  "Rotation(s) of the map about the vertical axis, degrees.")
      ->capture_default_str();
  auto* exp_opt = cmd->add_option("--exposure", *exposure,
                                  "Preview exposure in stops (default: automatic per image).");
  auto memory = std::make_shared<MemoryBudget>();
  add_memory_option(*cmd, *memory,
                    "Relight: what rendering bright sources may hold (the images of the LEDs "
                    "around them, at --source-pixels); over it they are relit by the LED cells, "
                    "with a note. The field itself is read a few MiB at a time whatever its size; "
                    "the sources' normals in bands within what they leave.");
  cmd->add_option("--coverage-deg", options->coverage_deg,
                  "Dome coverage radius around each LED, degrees (0: automatic).")
      ->capture_default_str();
  cmd->add_flag("!--no-bright-sources", options->bright_sources,
                "Fields: relight a map's sun or small lamp by the LED cells too, as one LED "
                "cell's light each (shadows at the LEDs' directions), instead of rendering it "
                "at its true direction with moving shadows.");
  cmd->add_flag("!--no-compact-sources", options->bright_sources,
                "Deprecated: --no-bright-sources.")
      ->group("");
  cmd->add_flag("!--no-source-geometry", options->source_geometry,
                "Fields: cast the bright sources' shadows by the flows between the LEDs' shadows "
                "alone, without the scene's shape recovered from them (which needs every LED's "
                "image in memory for seconds at 256^2; over --memory it is skipped, with a note).");
  cmd->add_option("--source-pixels", options->source_pixels,
                  "Fields: a field of more pixels has its bright sources (normals, shape, the "
                  "LEDs' shadows) made on it reduced to about this many, each pixel the mean of a "
                  "block, and brought back to its size by the detail of the LEDs around each "
                  "source: seconds at 12 megapixels instead of minutes. 0: at the field's size.")
      ->capture_default_str();
  cmd->add_option("--out", options->out_dir, "Output directory.")->required();
  add_quiet_flag(*cmd, *quiet);
  cmd->add_option("--temporal", options->temporal_file,
                  "Temporal maps from 'lightstage fit --time', rendered at --time (with "
                  "--edits: a time edit file, see relight/time/temporal_render.h).")
      ->check(CLI::ExistingFile);
  auto* time_opt = cmd->add_option("--time", *time_s,
                                   "With --temporal: scene time in seconds (any time; "
                                   "outside the captured steps it is flagged).");
  cmd->callback([options, quiet, exposure, exp_opt, light, time_s, time_opt, memory] {
    options->memory_bytes = memory->given_bytes();
    if (exp_opt->count() > 0) options->exposure_stops = *exposure;
    if (time_opt->count() > 0) options->time_s = *time_s;
    if (light->size() == 3)
      options->light_dir = Eigen::Vector3d((*light)[0], (*light)[1], (*light)[2]);
    if (const std::string problem = options->validate(); !problem.empty()) {
      throw CLI::ValidationError("relight", problem);
    }
    relight_and_report(*options, *quiet);
  });
}

}  // namespace ls::cli
