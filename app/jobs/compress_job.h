#pragma once
// Compress a field (or an .lp one-light set, imported on the way) into a compact representation:
// the lightstage PCA format, .ptm (PTM 1.2 RGB/LRGB) or .rti (HSH).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "app/jobs/job.h"
#include "lightstage/memory.h"

namespace ls::jobs {

struct CompressOptions {
  std::filesystem::path input;  // Field EXR, .lp file, or a folder holding one .lp.
  std::filesystem::path out;
  std::string format = "pca";  // pca | ptm | ptm-rgb | ptm-lrgb | hsh2 | hsh3 | hsh4
  // PCA: a positive number, auto (from the noise floor) or held-out (PcaRankRule::kHeldOutLights).
  std::string rank = "auto";
  int tile = 0;       // PCA tile size in pixels; 0: one global basis.
  double gain = 0.0;  // RTI files: display units per field unit; 0: brightest = white.
  // RTI files: "srgb" (empty: the default) fits and stores the sRGB codes of gain x the field, as
  // the RTI viewers show them; "linear" (.rti only: a .ptm cannot say so) stores gain x the field,
  // for lightstage's use. A PCA takes none: it holds the field's own values.
  std::string encoding;
  // For the field: a larger one is read in bands of rows (twice for PCA, three times with the
  // held-out rank rule). An .lp set its images cannot give in bands, with a budget given or
  // larger than the budget, is imported into a field file beside `out` first (in bands), and
  // compressed from it.
  MemoryBudget memory;
  std::string validate() const;
  std::string to_json() const;  // What a resumed run must share (CheckpointDir's identity).
};

struct CompressSummary {
  std::string representation;  // E.g. "pca k=12", "hsh3".
  std::string details;         // The builder's own summary (PCA rank choice, lights used).
  double bytes_per_pixel = 0.0;
  double raw_bytes_per_pixel = 0.0;  // The float field it came from, in memory.
  // On disk: the input (an EXR; an .lp set's images) and the file written.
  std::uintmax_t input_bytes = 0, output_bytes = 0;
  int band_rows = 0;     // Rows read at once: the height when read whole.
  int resumed_rows = 0;  // In bands: rows an earlier, killed run finished.
  int ranks = 1;         // .ptm/.rti: processes the bands were split over (MPI); rank 0 wrote.
  std::vector<std::string> warnings;  // What was assumed (a --rank above what the field gives).
};

// Throws InputError for bad options or inputs; the output is written only on success.
CompressSummary compress(const CompressOptions& options, const ProgressFn& progress = {});

// lightstage export openlime: a field (EXR, or an .lp set imported on the way) as an OpenLIME
// folder (relight/compact/plane_field.h: info.json and its planes), read whole.
struct OpenLimeExportOptions {
  std::filesystem::path input;  // Field EXR, .lp file, or a folder holding one .lp.
  std::filesystem::path out;    // The folder (made; its files replaced).
  std::string type = "rbf";     // rbf | bilinear (OpenLIME's types).
  int planes = 0;               // A multiple of 3; 0: the fewest the data needs.
  std::string image = "jpg";    // jpg (at `quality`, what relight writes) | png (lossless).
  int quality = 95;
  double gain = 0.0;  // Display units per field unit; 0: the brightest sample is white.
  // For the field: as CompressOptions::memory (three passes).
  MemoryBudget memory;
  std::string validate() const;
};

struct OpenLimeExportSummary {
  std::string representation;  // E.g. "rbf 9 planes".
  std::string chosen;          // What was chosen from the data: "sigma 0.11", "grid 10x10".
  int width = 0, height = 0, lights = 0;
  std::uintmax_t input_bytes = 0, output_bytes = 0;  // On disk: the input, the folder written.
  int band_rows = 0;                                 // Rows read at once; 0: whole.
};

// Throws InputError for bad options or inputs.
OpenLimeExportSummary export_openlime(const OpenLimeExportOptions& options,
                                      const ProgressFn& progress = {});

// lightstage render: a compact file (.ptm, .rti, the lightstage PCA format, or an OpenLIME
// folder of rbf or bilinear planes) relit under one distant light or an environment map: linear
// radiance in field units (the file's codes dequantised), as OUT.exr with an auto-exposed OUT.png
// beside it.
struct RenderOptions {
  std::filesystem::path input;        // A file, or an OpenLIME folder (its info.json).
  std::filesystem::path out;          // .exr
  std::vector<double> light;          // X Y Z toward the light, stage frame (+Y up); or
  std::filesystem::path environment;  // an environment map (EXR/HDR) ...
  double rotation_deg = 0.0;          // ... rotated about +Y.
  // A PCA (it keeps its LEDs' directions) under a map with a bright source (a sun, a lamp): the
  // source split off and rendered at its true direction from the PCA's reconstruction, as
  // `relight` does for a field (relight/sources/map_relight.h), the rest of the map by LED cells.
  bool bright_sources = true;
  // Fitted model maps (lightstage fit) on a shape instead of a compact file: "sphere",
  // "cylinder", "plane" or an OBJ mesh's path (relight/material/shape_render.h), the maps repeated
  // `tiles` times over it, a square image of `resolution` pixels (app/jobs/material_job.h).
  std::string shape;
  double tiles = 1.0;
  int resolution = 256;
  std::string validate() const;
};

struct RenderSummary {
  std::string representation;  // E.g. "hsh3", "ptm-lrgb", "pca k=12".
  int width = 0, height = 0;
  std::string sources;  // What was split off the map and rendered at its direction; empty: none.
  double preview_stops = 0;           // The PNG preview's exposure relative to the EXR, in stops.
  std::vector<std::string> warnings;  // What was assumed (a light beyond the captured ones).
};

RenderSummary render_compact(const RenderOptions& options);

}  // namespace ls::jobs
