#pragma once
// `lightstage bench fit`: per-pixel model fits against field relighting on the demo scene. Fit
// throughput of each model (Lambert, Oren-Nayar, Lambert + Torrance-Sparrow, Lambert + Phong, and
// the BIC choice), each by both solvers (relight::FitSolver: profiled, and LM on every candidate),
// and the BIC choice with basis materials (relight::FitMaterials),
// and the error of relighting from it under every map against ground truth, with
// the field's relighting on the same chart. Writes fit.csv, fit_error_vs_time.png and
// fit_error_vs_throughput.png.
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"

namespace ls::evaluation {

struct FitBenchOptions {
  std::filesystem::path out = "bench-out";
  int leds = 150;                           // LEDs on the Fibonacci dome.
  int resolution = 64;                      // Camera width and height.
  int repeats = 5;                          // Timed relights and model renders (median reported).
  std::vector<std::filesystem::path> maps;  // Environment maps (the CLI: the shipped ones).
  std::string validate() const;             // Empty when valid.
};

// One method under one map: "field" (relighting the field itself) or a fit configuration.
struct FitBenchRow {
  std::string method, map;
  double fit_s = 0, normals_s = 0, fit_pixels_per_s = 0;  // Zero for the field.
  double render_ms = 0;
  double time_to_frame_s = 0;  // Field: its relight; models: normals + fit + render.
  double relative_rmse = 0, psnr_db = 0;
  double flagged_fraction = 0;
  // Models only (evaluation/model_metrics.h): the fraction of pixels whose model differs from
  // their 3x3 neighbours' majority, the fraction of truly Lambertian pixels fitted with another
  // model, and the basis materials found (0: per-pixel).
  double speckle = 0, wrong_on_lambertian = 0;
  int materials = 0;
  // The BIC choices only: the relative RMSE of the model render under the map sampled on a
  // 128 x 64 grid within the dome's coverage, not one light per LED (0 when not rendered).
  double fine_relative_rmse = 0;
};

struct FitBenchSummary {
  std::string noise_source;  // Where the fits' noise model came from (FitOptions::noise_source).
  double noise_read_variance = 0, noise_shot_variance_per_unit = 0;
  std::vector<FitBenchRow> rows;
  std::filesystem::path csv;  // fit.csv; the charts beside it.
};

FitBenchSummary run_fit_bench(const FitBenchOptions& options, const ProgressFn& progress = {});

// fit_error_vs_time.png and fit_error_vs_throughput.png beside `csv` (a fit.csv), from it alone.
void write_fit_charts(const std::filesystem::path& csv);

}  // namespace ls::evaluation
