#pragma once
// Every bench's charts redrawn from the CSV files it wrote, without running the bench.
#include <filesystem>
#include <string>
#include <vector>

namespace ls::evaluation {

struct RedrawnCharts {
  std::vector<std::filesystem::path> drawn;  // The CSV files whose charts were drawn.
  std::vector<std::string> errors;           // Why the others' were not (each names its file).
};

// Redraws the charts of each bench CSV in `dir` (leds.csv, sun.csv, exposures.csv, fit.csv,
// fit_sweeps.csv, temporal.csv, temporal_held_out.csv, compact.csv, rti.csv, scale.csv) beside
// it; a CSV that cannot be drawn (e.g. it lacks a column its charts need) does not stop the
// others. InputError when gnuplot is missing or `dir` holds none of them.
RedrawnCharts redraw_bench_charts(const std::filesystem::path& dir);

}  // namespace ls::evaluation
