#pragma once
// Import an existing one-light-at-a-time set (an RTI .lp file or a DiLiGenT folder) as a
// reflectance field, with a preview of its most frontal light beside it.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "app/jobs/job.h"
#include "capture/olat_import.h"

namespace ls::jobs {

struct ImportJobSummary {
  capture::OlatFormat format = capture::OlatFormat::kRtiLp;
  capture::OlatImportSummary import;
  int lights = 0;
  double mebibytes = 0.0;
  std::filesystem::path preview;  // FIELD.preview.png
  int preview_light = 0;          // Index of the light it shows.
  int band_rows = 0;              // Rows of the field written at once: its height when whole.
  int ranks = 1;                  // Processes the lights were split over (MPI); rank 0 wrote.
};

// `options` as capture::import_olat takes them (validated there); `memory` as
// capture::import_olat_to_file takes it, unset MemoryBudget::kImageSetBytes (an import reads each
// image once and writes its field in bands: more memory than a few tens of rows does not make it
// faster); progress: "import".
ImportJobSummary import_set(const std::filesystem::path& source, const std::filesystem::path& out,
                            capture::OlatImportOptions options, const MemoryBudget& memory = {},
                            const ProgressFn& progress = {});

// A time-lapse: one set per time step, each imported as OUT_DIR/field_tNNN.exr (the layout `fit
// --time DIR` reads) with its scene time. `sources` may be one folder whose subfolders (sorted by
// name) are the sets. times_s: one per set, or empty with interval_s > 0 (set i at i *
// interval_s). InputErrors name what does not match.
struct ImportSeriesSummary {
  std::vector<ImportJobSummary> steps;
  std::vector<std::filesystem::path> sets, fields;
  std::vector<double> times_s;
};
std::vector<std::filesystem::path> series_sets(const std::vector<std::filesystem::path>& sources);
ImportSeriesSummary import_series(const std::vector<std::filesystem::path>& sources,
                                  const std::vector<double>& times_s, double interval_s,
                                  const std::filesystem::path& out_dir,
                                  const capture::OlatImportOptions& options,
                                  const MemoryBudget& memory = {}, const ProgressFn& progress = {});

}  // namespace ls::jobs
