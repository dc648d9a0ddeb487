// lightstage import: an existing one-light-at-a-time set (RTI .lp file or DiLiGenT folder) ->
// reflectance field (OpenEXR) + a PNG preview of one light's image beside it.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>

#include "app/cli/commands.h"
#include "app/cli/validators.h"
#include "app/jobs/import_job.h"
#include "app/jobs/ranks.h"
#include "lightstage/memory.h"
#include "lightstage/memory_option.h"

namespace ls::cli {
namespace {

namespace fs = std::filesystem;

// The images check: what it did, and each image it found inconsistent (and left out).
void print_consistency(const capture::OlatImportSummary& summary) {
  std::printf("  consistency: %s\n", summary.consistency.c_str());
  for (const std::string& image : summary.inconsistent) {
    std::fprintf(stderr, "warning: %s %s\n", summary.inconsistent_left_out() ? "left out" : "kept",
                 image.c_str());
  }
  if (summary.inconsistent_left_out()) {
    std::printf("  (--keep-all keeps every image; the field's lights keep their ids)\n");
  }
}

int print_import(const fs::path& source, const fs::path& out,
                 const capture::OlatImportOptions& options, const MemoryBudget& memory,
                 bool quiet) {
  // Under MPI rank 0 reports and prints; the others are silent.
  const bool root = jobs::Ranks::world().root();
  if (root) {
    std::printf("%s: %s\n", source.c_str(),
                capture::to_string(capture::detect_olat_format(source)));
  }
  const auto lock = lock_output(out);
  const jobs::ImportJobSummary job =
      jobs::import_set(source, out, options, memory, progress_printer(quiet || !root));
  if (!root) return 0;
  const capture::OlatImportSummary& summary = job.import;
  std::printf("  %d images, %s, %dx%d", summary.images, summary.pixel_format.c_str(),
              summary.source_width, summary.source_height);
  if (summary.width != summary.source_width || summary.height != summary.source_height) {
    std::printf(" -> field %dx%d (area-averaged)", summary.width, summary.height);
  }
  std::printf("\n  %d lights, direction z (toward the camera) from %.3f to %.3f\n", job.lights,
              summary.min_dir_z, summary.max_dir_z);
  std::printf("  transfer curve undone: %s%s\n", summary.transfer_undone.c_str(),
              summary.intensities_divided ? "; per-light RGB intensities divided out" : "");
  if (job.format == capture::OlatFormat::kDiligent) {
    std::printf("  %d pixels outside mask.png (zero samples)\n", summary.masked_out_pixels);
  }
  std::printf("  %.3f%% samples saturated (%lld)\n", 100.0 * summary.saturated_fraction,
              summary.saturated_samples);
  for (const std::string& note : summary.notes) std::printf("  note: %s\n", note.c_str());
  for (const std::string& warning : summary.warnings) {
    std::fprintf(stderr, "warning: %s\n", warning.c_str());
  }
  print_consistency(summary);
  if (!summary.light_placement.empty()) {
    std::printf("  lights: %s; the listed directions were off by %.2f deg (median), %.2f at most\n",
                summary.light_placement.c_str(), summary.listed_direction_error_median_deg,
                summary.listed_direction_error_max_deg);
  }
  std::printf(
      "wrote %s (%.1f MiB on disk, %.1f MiB as float in memory) and %s (light %d), %.2f s\n",
      out.c_str(), double(fs::file_size(out)) / (1 << 20), job.mebibytes, job.preview.c_str(),
      job.preview_light, summary.seconds);
  std::printf("  %s\n", storage_line(summary.storage, summary.half_check,
                                     double(fs::file_size(out)) / (1 << 20))
                            .c_str());
  if (job.band_rows < summary.height || job.ranks > 1) {
    std::printf("written in bands of %d rows through a spill file beside it", job.band_rows);
    if (job.ranks > 1) std::printf(", the images read by %d MPI ranks", job.ranks);
    if (summary.resumed_lights > 0) {
      std::printf(" (%d images taken from an interrupted run)", summary.resumed_lights);
    }
    std::printf("\n");
  }
  std::printf("peak memory %.1f MiB\n", double(peak_resident_bytes()) / (1 << 20));
  return 0;
}

int print_series(const std::vector<fs::path>& sources, const std::vector<double>& times,
                 double interval_s, const fs::path& out, const capture::OlatImportOptions& options,
                 const MemoryBudget& memory, bool quiet) {
  const auto lock = lock_output(out);
  const jobs::ImportSeriesSummary series = jobs::import_series(
      sources, times, interval_s, out, options, memory, progress_printer(quiet));
  for (size_t i = 0; i < series.steps.size(); ++i) {
    const capture::OlatImportSummary& s = series.steps[i].import;
    std::printf("%s -> %s: t = %g s, %d images, field %dx%d, %.3f%% samples saturated\n",
                series.sets[i].c_str(), series.fields[i].filename().c_str(), series.times_s[i],
                s.images, s.width, s.height, 100.0 * s.saturated_fraction);
    if (!s.inconsistent.empty()) print_consistency(s);
  }
  std::printf("wrote %zu time steps to %s (fit them with: lightstage fit --time %s)\n",
              series.steps.size(), out.c_str(), out.c_str());
  std::printf("peak memory %.1f MiB\n", double(peak_resident_bytes()) / (1 << 20));
  return 0;
}

}  // namespace

void add_import_command(CLI::App& app) {
  auto options = std::make_shared<capture::OlatImportOptions>();
  auto sources = std::make_shared<std::vector<fs::path>>();
  auto out = std::make_shared<fs::path>();
  auto times = std::make_shared<std::vector<double>>();
  auto interval = std::make_shared<double>(0.0);
  auto quiet = std::make_shared<bool>(false);
  auto linear = std::make_shared<bool>(false), srgb = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand(
      "import",
      "Import an existing one-light-at-a-time photo set as a reflectance field: an RTI set "
      "described by an .lp file (N, then 'image x y z' per line) or a DiLiGenT photometric-stereo "
      "folder (filenames.txt, light_directions.txt, light_intensities.txt, mask.png). Undoes the "
      "transfer curve (default: sRGB for .lp sets, linear for DiLiGenT), divides by each light's "
      "intensity, and writes the field plus FIELD.preview.png.");
  cmd->add_option("source", *sources,
                  "An .lp file (or a folder with one) or a DiLiGenT folder; for a time-lapse, one "
                  "per time step, or one folder whose subfolders (by name) are the steps.")
      ->required();
  cmd->add_option("--out", *out,
                  "Field file to write (.exr); for a time-lapse, a folder: field_t000.exr, ...")
      ->required();
  cmd->add_option("--time", *times,
                  "Scene time of the set in seconds (default 0); for a time-lapse, one per set.");
  cmd->add_option("--interval", *interval,
                  "Time-lapse: seconds between consecutive sets (set i at i * S), instead of "
                  "--time.")
      ->check(kPositive);
  auto* gamma = cmd->add_option("--gamma", options->gamma,
                                "Undo a plain gamma curve: linear = code^G (G in (0, 10]).");
  auto* linear_flag = cmd->add_flag("--linear", *linear, "The images are linear already.");
  auto* srgb_flag = cmd->add_flag("--srgb", *srgb, "Undo the sRGB curve (default for .lp sets).");
  gamma->excludes(linear_flag)->excludes(srgb_flag);
  linear_flag->excludes(srgb_flag);
  cmd->add_option("--max-size", options->max_size,
                  "Downsize (area averaging) so that the larger side is at most N pixels.")
      ->check(CLI::Range(1, 1 << 20));
  cmd->add_flag("--keep-all", options->keep_all,
                "Keep every image: by default each is checked against what the others predict at "
                "its light, and those that disagree (shifted, another light's, black) are left "
                "out and listed.");
  auto circles = std::make_shared<std::vector<double>>();
  auto* circle =
      cmd->add_option(
             "--circle", *circles,
             "A mirror sphere in every image: cx,cy,r in the images' pixels (x right, y down, "
             "pixel centres at +0.5); repeat per sphere. The lights are placed from their "
             "highlights: one sphere gives directions, two give positions (near lights: each "
             "pixel sees its own direction and distance, the falloff divided out). The "
             "spheres rest on the plane the object lies on.")
          ->delimiter(',')
          ->check(kFinite);
  cmd->add_option("--stage", options->stage_file,
                  "A calibrated stage file whose LEDs are the set's lights, in order: their "
                  "directions, positions (near lights, as a build's) and irradiance replace what "
                  "the set lists, and its camera gives the view.")
      ->check(CLI::ExistingFile)
      ->excludes(circle);
  cmd->add_option("--sphere-radius", options->spheres.radius_m,
                  "The spheres' radius in metres, for light positions in metres (otherwise a "
                  "nominal scale: the normals do not depend on it).")
      ->check(kPositive)
      ->needs(circle);
  cmd->add_option("--focal-length-px", options->spheres.focal_length_px,
                  "With --circle: the camera's focal length in pixels of the images (a pinhole "
                  "camera looking straight down; needs --sphere-radius). Without it the view is "
                  "taken as orthographic, which errs by about the spheres' angle off the axis.")
      ->check(kPositive)
      ->needs(circle);
  cmd->add_flag("--drop-saturated", options->zero_saturated,
                "Write saturated samples (maximum code) as 0, so fits leave them out as shadowed; "
                "default: keep them as lower bounds.");
  auto memory = std::make_shared<MemoryBudget>();
  add_memory_option(*cmd, *memory,
                    "Import: the field's values; a larger field is written in bands, each image "
                    "spilled to a file beside --out that needs the field's size free.",
                    "32 MiB (each image is read once: more rows do not make it faster)");
  auto storage = std::make_shared<std::string>("auto");
  cmd->add_option("--storage", *storage,
                  "How the field file holds the values: half floats where the field relit from "
                  "them stays within 1e-3 of the floats (and their rounding within 0.25 sigma of "
                  "a measured noise), else floats (auto); or always half or float.")
      ->check(CLI::IsMember({"auto", "half", "float"}))
      ->capture_default_str();
  add_quiet_flag(*cmd, *quiet);
  cmd->callback([options, sources, out, times, interval, quiet, linear, srgb, gamma, memory,
                 storage, circles] {
    if (circles->size() % 3 != 0) {
      throw CLI::ValidationError("--circle", "expected cx,cy,r per sphere, got " +
                                                 std::to_string(circles->size()) + " numbers");
    }
    options->spheres.outlines = capture::outlines_from_circles(*circles);
    options->storage = capture::parse_storage_choice("--storage", *storage);
    if (*linear) options->transfer = capture::TransferCurve::kLinear;
    if (*srgb) options->transfer = capture::TransferCurve::kSrgb;
    if (gamma->count() > 0) options->transfer = capture::TransferCurve::kGamma;
    if (jobs::series_sets(*sources).size() > 1 || times->size() > 1 || *interval > 0) {
      print_series(*sources, *times, *interval, *out, *options, *memory, *quiet);
      return;
    }
    if (!times->empty()) options->scene_time_s = times->front();
    print_import(jobs::series_sets(*sources).front(), *out, *options, *memory, *quiet);
  });
}

}  // namespace ls::cli
