#pragma once
// The lightstage subcommands. Each adds itself to the CLI11 app; parsing and printing live here,
// the work in the libraries. Exit codes: 0 done, 1 usage, 2 bad input, 3 hardware fault,
// 4 frames could not be saved (resumable), 130 interrupted (resumable).
#include <filesystem>
#include <string>
#include <vector>

#include "app/jobs/capture_job.h"

namespace CLI {
class App;
}

namespace ls::cli {

inline constexpr int kExitInputError = 2;
inline constexpr int kExitHardwareError = 3;
inline constexpr int kExitStorageError = 4;  // Frames could not be saved (disk full); resumable.
inline constexpr int kExitInterrupted = 130;

void add_capture_command(CLI::App& app);
void add_build_command(CLI::App& app);
void add_relight_command(CLI::App& app);
void add_demo_command(CLI::App& app);
void add_stage_command(CLI::App& app);
void add_envmaps_command(CLI::App& app);
void add_bench_command(CLI::App& app);
// `bench compact` (needs add_bench_command first) and `compress` (compact_command.cc).
void add_compact_commands(CLI::App& app);
void add_devices_command(CLI::App& app);
void add_check_command(CLI::App& app);
void add_calibrate_command(CLI::App& app);
void add_fit_command(CLI::App& app);
void add_import_command(CLI::App& app);
void add_view_command(CLI::App& app);  // view_command.cc: the interactive viewer.

// Steps shared by the demo and the single-step commands.
// Runs the capture job with progress, Ctrl-C handling and the operator's messages; the exit code.
int capture_session(const jobs::CaptureOptions& options, bool quiet);

int build_field_file(const std::filesystem::path& session_dir, const std::filesystem::path& out,
                     int time_step, bool quiet);

struct RelightRequest {
  std::filesystem::path field_file;
  std::vector<std::filesystem::path> maps;
  std::vector<double> rotations_deg{0.0};
  double exposure_stops = 0.0;
  bool auto_exposure = true;
  double coverage_deg = 0.0;
  std::filesystem::path out_dir;
  bool quiet = false;
  // --models: render fitted model maps (relight/fit/model_render.h) instead of the field; with a
  // field too, the field fills the flagged pixels. --edits: an edit file applied to the maps.
  std::filesystem::path models_file;
  std::filesystem::path edits_file;
  int directions_width = 64;      // Lat-long grid the map is integrated on for models.
  std::vector<double> light_dir;  // --light X Y Z (models): a directional light of unit irradiance.
};
// Returns the written preview PNGs with their labels, for contact sheets.
struct RelitOutput {
  std::filesystem::path png;
  std::string label;
};
std::vector<RelitOutput> relight_field_file(const RelightRequest& request);

// Lays PNG previews out in a labelled grid.
void write_contact_sheet(const std::filesystem::path& out, const std::vector<RelitOutput>& tiles,
                         const std::string& title, int tile_size = 256);

// Shipped maps: data/envmaps in the source tree, plus ../shared/data/envmaps when present.
std::vector<std::filesystem::path> shipped_environment_maps(bool include_shared);
std::filesystem::path data_dir();

// lightstage fit: field -> model maps (relight/fit/fit.h).
struct FitRequest {
  std::filesystem::path field_file;
  std::filesystem::path out;
  bool phong = false;
  std::string method = "robust";  // Photometric-stereo normals: "robust" or "ls".
  bool quiet = false;
};
int fit_field_file(const FitRequest& request);

}  // namespace ls::cli
