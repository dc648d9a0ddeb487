#pragma once
// `lightstage bench leds`: relighting accuracy and speed as the number of LEDs grows. For each dome
// size, a simulated capture of the demo scene built into a field, relit under each map (median
// time over repeats) by LED cells alone and with the map's bright sources split off and rendered
// at their true direction (relight/sources/field_sources.h), and compared with ground truth
// rendered directly from the scene. Writes leds.csv and two charts (PSNR against relight time;
// error against LEDs).
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"

namespace ls::evaluation {

struct LedBenchOptions {
  std::filesystem::path out = "bench-out";
  std::vector<int> counts{20, 40, 80, 150, 300};  // LEDs of the Fibonacci domes.
  int resolution = 128;                           // Camera width and height.
  int repeats = 21;                               // Timed relights (median reported).
  // Maps with a bright source are also relit turned about the vertical to this many azimuths
  // (evenly spaced), the median error reported: one position of a small source says more about
  // how near it happens to fall to an LED than about the dome's density. 0: not turned.
  int turns = 8;
  std::vector<std::filesystem::path> maps;  // Environment maps (the CLI: the shipped ones).
  std::string validate() const;             // Empty when valid.
};

struct LedBenchRow {
  int leds = 0;
  std::string map;     // The map file's stem.
  std::string method;  // "cells" (the whole map by LED cells) or "cells + sources" (split off).
  int turns = 0;       // > 0: relative_rmse and psnr_db are the median of this many turns; untimed.
  double relative_rmse = 0, psnr_db = 0;
  double relight_ms = 0, relight_gb_per_s = 0, light_weights_ms = 0;
  double uncovered_fraction = 0;
};

struct LedBenchSummary {
  std::vector<LedBenchRow> rows;
  std::filesystem::path csv;  // leds.csv; the charts beside it.
  // Maps with a bright source, largest dome: by cells, with sources and ground truth, in that
  // order (compare/*.png, at the truth's exposure), with labels.
  struct ComparisonImage {
    std::filesystem::path png;
    std::string label;
  };
  std::vector<ComparisonImage> comparison;
};

LedBenchSummary run_led_bench(const LedBenchOptions& options, const ProgressFn& progress = {});

// leds_psnr_vs_time.png, leds_error_vs_count.png and (with turned rows)
// leds_error_vs_count_turned.png beside `csv` (a leds.csv), from it alone.
void write_led_charts(const std::filesystem::path& csv);

}  // namespace ls::evaluation
