#pragma once
// `lightstage bench exposures`: each LED's exposures chosen from an earlier session
// (capture/exposure_choice.h) against the whole bracket, on the demo scene and on a
// high-dynamic-range one (a near-mirror sphere beside a dark cloth): LED frames, exposure and
// capture time, and the field's error against the simulator's truth. CSV and a chart.
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"

namespace ls::evaluation {

struct ExposurePlanOutcome {
  int led_frames = 0;       // Per time step.
  double exposure_s = 0;    // Summed over those frames.
  double capture_s = 0;     // Each frame at least 1 / camera_fps (a sensor's read-out).
  double median_error = 0;  // Relative RMSE per LED against the noise-free render, over the LEDs
  double p90_error = 0;     // that light the view, without pixels clipped at the shortest step.
};

struct ExposureBenchRow {
  std::string scene;
  ExposurePlanOutcome whole, chosen;
};

// Captures `scene` on `stage` at the whole bracket in dir/whole, chooses each LED's exposures from
// it, captures again in dir/chosen (the same camera seed) and measures both fields.
ExposureBenchRow compare_exposure_plans(const std::string& scene_name, const sim::Scene& scene,
                                        const Stage& stage, const std::filesystem::path& dir,
                                        double camera_fps);

struct ExposureBenchOptions {
  std::filesystem::path out = "bench_out";
  int resolution = 96;
  double camera_fps = 10.0;  // A machine-vision sensor of 12-50 MP reads out at about this rate.
  std::filesystem::path hdr_scene;  // data/scenes/hdr.json.
};

struct ExposureBenchSummary {
  std::vector<ExposureBenchRow> rows;
  std::filesystem::path csv;
};

ExposureBenchSummary run_exposure_bench(const ExposureBenchOptions& options,
                                        const ProgressFn& progress = {});

// exposures_error_vs_time.png beside `csv` (an exposures.csv), from it alone.
void write_exposure_chart(const std::filesystem::path& csv);

}  // namespace ls::evaluation
