#pragma once
// Import an existing one-light-at-a-time set (an RTI .lp file or a DiLiGenT folder) as a
// reflectance field, with a preview of its most frontal light beside it.
#include <cstddef>
#include <filesystem>
#include <string>

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
};

// `options` as capture::import_olat takes them (validated there); memory_bytes as
// capture::import_olat_to_file (0: default); progress: "import".
ImportJobSummary import_set(const std::filesystem::path& source, const std::filesystem::path& out,
                            capture::OlatImportOptions options, std::size_t memory_bytes = 0,
                            const ProgressFn& progress = {});

}  // namespace ls::jobs
