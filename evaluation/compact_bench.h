#pragma once
// `lightstage bench compact`: every compact representation on the simulated RTI scenes (matte,
// glossy, shadowed; sim/rti_scenes.h) and the real RTI set: bytes per pixel, build time, relight
// time per frame, PSNR and SSIM on held-out LEDs (evaluation/leave_lights_out.h). Writes
// compact.csv and, per scene, compact_<scene>_psnr_vs_time.png and
// compact_<scene>_psnr_vs_bytes.png.
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"
#include "evaluation/leave_lights_out.h"

namespace ls::evaluation {

struct CompactBenchOptions {
  std::filesystem::path out = "bench-out";
  bool quick = false;                     // 32x32 scenes, no model fits.
  int repeats = 15;                       // Timed relights (median reported).
  std::filesystem::path environment_map;  // Lighting for the relight timings.
  std::filesystem::path real_lp;          // The real RTI set (.lp); skipped when absent.
  std::string validate() const;           // Empty when valid.
};

struct CompactBenchRow {
  std::string scene, family, name;  // family: the chart series; name: the representation's own.
  LeaveLightsOutResult result;
  double relight_ms = 0;
  bool automatic = false;  // The software's own choice (PCA, automatic rank).
  bool pareto_bytes = false, pareto_time = false;  // On the PSNR front against bytes, time.
};

struct CompactBenchSummary {
  std::vector<CompactBenchRow> rows;  // Scene by scene.
  std::vector<std::string> notes;     // E.g. the real set is absent.
  std::filesystem::path csv;          // compact.csv; the charts beside it.
};

CompactBenchSummary run_compact_bench(const CompactBenchOptions& options,
                                      const ProgressFn& progress = {});

// compact_<scene>_psnr_vs_time.png and compact_<scene>_psnr_vs_bytes.png (the scene's first
// word) beside `csv` (a compact.csv), from it alone.
void write_compact_charts(const std::filesystem::path& csv);

}  // namespace ls::evaluation
