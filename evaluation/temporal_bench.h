#pragma once
// `lightstage bench temporal`: time-varying BRDF fits (relight/time/temporal_fit.h) on the
// simulator's time-varying scene as the number of time steps grows: fit time per pixel (per-step
// BRDF fits and temporal model fits) and the error against ground truth (rendering at uncaptured
// times, and the recovered rates). Writes temporal.csv, temporal_error_vs_steps.png and
// temporal_time_vs_steps.png.
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"

namespace ls::evaluation {

struct TemporalBenchOptions {
  std::filesystem::path out = "bench-out/temporal";
  std::vector<int> steps{3, 5, 8, 12, 20};  // Numbers of time steps, one row each.
  int leds = 40;                            // LEDs on the Fibonacci dome.
  int width = 32;
  int height = 24;
  double duration_s = 600;       // Scene seconds covered by the steps.
  std::string validate() const;  // Empty when valid.
};

struct TemporalBenchRow {
  int steps = 0;
  double step_fit_us_per_pixel_step = 0;
  double temporal_fit_us_per_pixel = 0;
  double render_error = 0;       // Relative RMS at uncaptured times vs the ideal one-light truth.
  double median_rate_error = 0;  // |rate / true - 1| over varying pixels given a process.
  double varying_recall = 0;     // Varying pixels given a non-constant model.
  double static_constant = 0;    // Static pixels given the constant model.
};

struct TemporalBenchSummary {
  std::vector<TemporalBenchRow> rows;
  std::filesystem::path csv;  // temporal.csv; the charts beside it.
};

TemporalBenchSummary run_temporal_bench(const TemporalBenchOptions& options,
                                        const ProgressFn& progress = {});

}  // namespace ls::evaluation
