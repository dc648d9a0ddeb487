#pragma once
// Relight a reflectance field, fitted models (optionally edited) or time-varying models under
// environment maps (and, for models, one distant light): linear EXR + tone-mapped PNG per map and
// rotation, and contact_sheet.png.
#include <Eigen/Core>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "app/jobs/job.h"
#include "relight/sources/map_relight.h"

namespace ls::jobs {

struct RelightOptions {
  std::filesystem::path field_file;   // Reflectance field; with models_file, fills flagged pixels.
  std::filesystem::path models_file;  // Model maps of `lightstage fit`.
  std::filesystem::path temporal_file;  // Temporal maps of `lightstage fit --time`.
  std::optional<double> time_s;         // With temporal_file: the scene time to render.
  std::filesystem::path edits_file;     // Model edits (models) or time edits (temporal).
  std::vector<std::filesystem::path> maps;
  std::vector<double> rotations_deg{0.0};
  std::optional<Eigen::Vector3d> light_dir;  // Models: one distant light of unit irradiance.
  std::optional<double> exposure_stops;      // Previews; empty: automatic per image.
  double coverage_deg = 0.0;                 // Dome coverage around each LED; 0: automatic.
  // Fields: a map's bright sources (a sun, a lamp) are split off and rendered at their true
  // direction with moving shadows (relight/sources/map_relight.h), the rest by LED cells.
  bool bright_sources = true;
  // Their shadows: by the scene's shape recovered from every LED's shadows where it agrees with
  // the LEDs around the source (relight/sources/shadow_geometry.h), else by the flows alone.
  bool source_geometry = true;
  // A field of more pixels has its sources made on it reduced to about this many, brought back to
  // its size by the LEDs' own detail (MapRelightOptions::source_pixels); 0: at its size.
  std::size_t source_pixels = relight::MapRelightOptions{}.source_pixels;
  // What rendering them may hold (relight::FieldSources::bytes_needed); 0: half of the memory
  // available. Over it they are relit by the cells, and the output's detail says so. Models and
  // temporal maps are read in bands of rows within what the full-size outputs leave of it.
  std::size_t memory_bytes = 0;
  int directions_width = 64;  // Models: lat-long grid the map is integrated on.
  std::filesystem::path out_dir;
  // Empty when the options make sense, else what is wrong, naming the option.
  std::string validate() const;
  std::string to_json() const;  // Recorded in every output EXR (kOptionsAttribute).
};

struct RelitImage {
  std::filesystem::path exr, png;
  std::string label;
  std::string detail;  // Timings and coverage, one line for the operator.
};

struct RelightSummary {
  std::vector<RelitImage> images;
  std::vector<std::string> edit_reports;  // One line per edit: how many pixels it changed.
  std::filesystem::path contact_sheet;
  // Temporal: the captured span and how many varying pixels were extrapolated beyond it.
  double first_time_s = 0.0, last_time_s = 0.0;
  int extrapolated_pixels = 0;
  // Relighting a field: the pass over it (reading its bands and relighting them under every map),
  // without the light weights and the writing; and the field file's bytes.
  double field_pass_s = 0.0;
  double field_file_bytes = 0.0;
  int ranks = 1;  // A field relit under MPI: the processes its bands were split over.
};

// Throws InputError for bad options (validate()) or inputs, before out_dir is written.
RelightSummary relight(const RelightOptions& options, const ProgressFn& progress = {});

}  // namespace ls::jobs
