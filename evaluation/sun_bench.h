#pragma once
// `lightstage bench sun`: a small source between the LEDs. On the built-in dome and the
// demo scene, a disc source (default 2 deg radius, unit irradiance) is
//  - swept in small steps from an LED's direction to the middle of the three LEDs around it, and
//  - turned through a full circle about the vertical at its elevation,
// and the field relit under it by LED cells alone and with the source split off and rendered at
// its true direction (its shadows by the flows between the LEDs' shadows alone, and with the
// scene's recovered shape, as `relight` does), each against ground truth rendered from the scene;
// and the source rendered with the scene's exact visibility of it (traced in the simulator)
// instead: what is left then is the shading's error, the rest the shadows'. Writes
// sun.csv and sun_sweep.png, sun_turn.png (error against position, all four) and
// sun_error_vs_time.png (error against the time per frame), and each position's images in
// sun_frames/ (by cells, with the source, ground truth).
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"

namespace ls::evaluation {

struct SunBenchOptions {
  std::filesystem::path out = "bench-out";
  int resolution = 128;       // Camera width and height.
  double radius_deg = 2.0;    // Of the source.
  double elevation_deg = 50;  // Of the LED the sweep starts from (the nearest one) and the turn.
  int sweep_steps = 8;        // Steps from the LED to the middle of its triangle.
  int turn_steps = 24;        // Positions around the full turn.
  int repeats = 5;            // Timed relights (median reported).
  std::string validate() const;
};

struct SunBenchRow {
  std::string path;     // "sweep" or "turn".
  double position = 0;  // Sweep: 0 at the LED, 1 in the middle of three; turn: azimuth, degrees.
  double angle_to_nearest_led_deg = 0;
  double cells_rmse = 0, sources_rmse = 0;  // Relative RMSE against ground truth.
  double flows_rmse = 0;                    // The sources' shadows by the flows alone.
  double exact_visibility_rmse = 0;         // The sources' render with the exact visibility.
  double cells_ms = 0, sources_ms = 0, flows_ms = 0;  // Relight time per frame (median).
};

struct SunBenchSummary {
  std::vector<SunBenchRow> rows;
  double sources_setup_ms = 0;  // Normals, LED shadows and the shape, once per field.
  double flows_setup_ms = 0;    // Normals and LED shadows alone.
  std::filesystem::path csv;
};

SunBenchSummary run_sun_bench(const SunBenchOptions& options, const ProgressFn& progress = {});

// sun_<path>.png (sun_sweep, sun_turn) and sun_error_vs_time.png beside `csv` (a sun.csv), from it
// alone.
void write_sun_charts(const std::filesystem::path& csv);

}  // namespace ls::evaluation
