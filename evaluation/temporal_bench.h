#pragma once
// `lightstage bench temporal`: time-varying BRDF fits (relight/time/temporal_fit.h) on the
// simulator's time-varying scene as the number of time steps grows: fit time per pixel (per-step
// BRDF fits and temporal model fits) and the error against ground truth (rendering at uncaptured
// times, and the recovered rates). Writes temporal.csv, temporal_error_vs_steps.png and
// temporal_time_vs_steps.png. Then the rise-and-fall scene's time lapse
// (evaluation/temporal_held_out.h) captured at a growing number of its steps: the error at the
// steps held out of the temporal fit, of its models chosen by BIC alone, of the processes alone, of
// the per-step fits interpolated, of linear interpolation of the captured images and of the nearest
// captured image, as captured and five times darker (temporal_held_out{,_dark}.csv and
// temporal_held_out{,_dark}_vs_steps.png), and a time edit and an effect transfer on its curves
// over time (temporal_edits.png).
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
  double duration_s = 600;  // Scene seconds covered by the steps.
  // The held-out part: a time lapse of this many steps over 1200 s on a 151-LED dome, captured at
  // each of these numbers of its steps (evenly spread); empty: left out.
  int lapse_steps = 25;
  std::vector<int> captured{3, 4, 5, 7, 9, 13};
  std::string validate() const;  // Empty when valid.
};

struct HeldOutBenchRow {
  double exposure = 1;       // 1: as captured; 0.2: five times darker, the same sensor noise.
  bool dim_samples = false;  // The fits readmit the dim samples (FitOptions::readmit_dim_samples).
  int captured = 0;
  // Relative RMS at the steps held out, both varying materials together (HeldOutScores).
  double fit = 0, by_bic_alone = 0, processes_only = 0, step_fits_interpolated = 0, linear = 0,
         nearest = 0;
  // At the captured steps: the temporal fit, each step's own fit, the photographs (their noise).
  double fit_at_captured = 0, step_fits_at_captured = 0, photos_at_captured = 0;
  int curve_families = 0;
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
  std::vector<HeldOutBenchRow> held_out;
  std::filesystem::path csv;  // temporal.csv; the charts beside it.
};

TemporalBenchSummary run_temporal_bench(const TemporalBenchOptions& options,
                                        const ProgressFn& progress = {});

// temporal_error_vs_steps.png and temporal_time_vs_steps.png beside `csv` (a temporal.csv), from
// it alone.
void write_temporal_charts(const std::filesystem::path& csv);
// temporal_held_out_vs_steps.png beside `csv` (a temporal_held_out.csv; for
// temporal_held_out_dark.csv, temporal_held_out_dark_vs_steps.png), from it alone.
void write_temporal_held_out_chart(const std::filesystem::path& csv);

}  // namespace ls::evaluation
