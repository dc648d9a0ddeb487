// lightstage import: an existing one-light-at-a-time set (RTI .lp file or DiLiGenT folder) ->
// reflectance field (OpenEXR) + a PNG preview of one light's image beside it.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>
#include <optional>

#include "capture/field.h"
#include "capture/olat_import.h"
#include "app/cli/commands.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/progress.h"

namespace ls::cli {
namespace {

namespace fs = std::filesystem;

// The light nearest the camera (+Z): the most evenly lit of the images, for the preview.
int frontal_light(const capture::ReflectanceField& field) {
  int best = 0;
  for (int l = 1; l < field.num_lights(); ++l) {
    if (field.lights()[l].dir_in_stage.z() > field.lights()[best].dir_in_stage.z()) best = l;
  }
  return best;
}

Image light_image(const capture::ReflectanceField& field, int light) {
  Image image(field.width(), field.height(), 3);
  for (int y = 0; y < field.height(); ++y) {
    for (int x = 0; x < field.width(); ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = field.at(x, y, light, c);
    }
  }
  return image;
}

struct ImportArgs {
  fs::path source, out;
  std::optional<double> gamma;
  bool linear = false;
  bool srgb = false;
  int max_size = 0;
  bool drop_saturated = false;
  bool quiet = false;
};

int import_set(const ImportArgs& args) {
  capture::OlatImportOptions options;
  if (args.linear) options.transfer = capture::TransferCurve::kLinear;
  if (args.srgb) options.transfer = capture::TransferCurve::kSrgb;
  if (args.gamma) {
    options.transfer = capture::TransferCurve::kGamma;
    options.gamma = *args.gamma;
  }
  options.max_size = args.max_size;
  options.zero_saturated = args.drop_saturated;
  const capture::OlatFormat format = capture::detect_olat_format(args.source);
  std::printf("%s: %s\n", args.source.c_str(), capture::to_string(format));
  std::unique_ptr<ProgressReporter> progress;
  options.on_progress = [&](int done, int total) {
    if (!progress) progress = std::make_unique<ProgressReporter>("import", total, args.quiet);
    progress->update(done);
  };
  capture::OlatImportSummary summary;
  const capture::ReflectanceField field = capture::import_olat(args.source, options, &summary);
  if (progress) progress->done();
  capture::write_field(args.out, field);

  const int light = frontal_light(field);
  const Image preview = light_image(field, light);
  fs::path preview_path = args.out;
  preview_path.replace_extension(".preview.png");
  write_png_preview(preview_path, preview, auto_exposure_stops(preview));

  std::printf("  %d images, %s, %dx%d", summary.images, summary.pixel_format.c_str(),
              summary.source_width, summary.source_height);
  if (summary.width != summary.source_width || summary.height != summary.source_height) {
    std::printf(" -> field %dx%d (area-averaged)", summary.width, summary.height);
  }
  std::printf("\n  %d lights, direction z (toward the camera) from %.3f to %.3f\n",
              field.num_lights(), summary.min_dir_z, summary.max_dir_z);
  std::printf("  transfer curve undone: %s%s\n", summary.transfer_undone.c_str(),
              summary.intensities_divided ? "; per-light RGB intensities divided out" : "");
  if (format == capture::OlatFormat::kDiligent) {
    std::printf("  %d pixels outside mask.png (zero samples)\n", summary.masked_out_pixels);
  }
  std::printf("  %.3f%% samples saturated (%lld)\n", 100.0 * summary.saturated_fraction,
              summary.saturated_samples);
  for (const std::string& note : summary.notes) std::printf("  note: %s\n", note.c_str());
  std::printf("wrote %s (%.1f MiB) and %s (light %d), %.2f s\n", args.out.c_str(),
              field.bytes() / 1048576.0, preview_path.c_str(), light, summary.seconds);
  return 0;
}

}  // namespace

void add_import_command(CLI::App& app) {
  auto args = std::make_shared<ImportArgs>();
  auto* cmd = app.add_subcommand(
      "import",
      "Import an existing one-light-at-a-time photo set as a reflectance field: an RTI set "
      "described by an .lp file (N, then 'image x y z' per line) or a DiLiGenT photometric-stereo "
      "folder (filenames.txt, light_directions.txt, light_intensities.txt, mask.png). Undoes the "
      "transfer curve (default: sRGB for .lp sets, linear for DiLiGenT), divides by each light's "
      "intensity, and writes the field plus FIELD.preview.png.");
  cmd->add_option("source", args->source,
                  "An .lp file (or a folder with one) or a DiLiGenT folder.")
      ->required();
  cmd->add_option("--out", args->out, "Field file to write (.exr).")->required();
  auto* gamma = cmd->add_option("--gamma", args->gamma,
                                "Undo a plain gamma curve: linear = code^G (G in (0, 10]).");
  auto* linear = cmd->add_flag("--linear", args->linear, "The images are linear already.");
  auto* srgb = cmd->add_flag("--srgb", args->srgb, "Undo the sRGB curve (default for .lp sets).");
  gamma->excludes(linear)->excludes(srgb);
  linear->excludes(srgb);
  cmd->add_option("--max-size", args->max_size,
                  "Downsize (area averaging) so that the larger side is at most N pixels.")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--drop-saturated", args->drop_saturated,
                "Write saturated samples (maximum code) as 0, so fits leave them out as shadowed; "
                "default: keep them as lower bounds.");
  cmd->add_flag("--quiet", args->quiet, "No progress output.");
  cmd->callback([args] { import_set(*args); });
}

}  // namespace ls::cli
