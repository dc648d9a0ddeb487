#pragma once
// Build a session's reflectance field (one time step, or one field per time step).
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "app/jobs/job.h"
#include "capture/build_field.h"

namespace ls::jobs {

struct BuildJobOptions {
  std::filesystem::path session_dir;
  std::filesystem::path out;  // Field file; with all_time_steps, the directory of field_tNNN.exr.
  int time_step = 0;
  bool all_time_steps = false;
  MemoryBudget memory;  // For the field's values (capture::BuildOptions::memory).
  // How the file holds its values: "auto" (half where capture::check_half passes,
  // capture/half_storage.h), "half" or "float".
  std::string storage = "auto";
  bool correct_drift = false;  // capture::BuildOptions::correct_drift.
  std::string validate() const;
  std::string to_json() const;  // Recorded in every field written (kOptionsAttribute).
};

struct BuiltField {
  std::filesystem::path file;
  int time_step = 0;
  double scene_time_s = 0.0;
  int width = 0, height = 0, lights = 0;
  double mebibytes = 0.0;       // The field's values in memory (float).
  double file_mebibytes = 0.0;  // The file (half storage: about half of that).
  int band_rows = 0;            // Rows built at once: the height when built in memory.
  int ranks = 1;  // Processes the LEDs' merges were split over (MPI); rank 0 wrote the field.
  std::vector<int> missing_led_ids;  // Missing or dead LEDs, excluded from relighting.
  capture::BuildSummary build;
};

struct BuildJobSummary {
  std::vector<BuiltField> fields;
  double reference_z_m = 0.0;  // Reference plane of near LEDs (stage calibration).
};

// Throws InputError for bad options, a damaged session or a time step outside the session.
BuildJobSummary build(const BuildJobOptions& options, const ProgressFn& progress = {});

}  // namespace ls::jobs
