#include "evaluation/bench_charts.h"

#include "evaluation/chart.h"
#include "evaluation/compact_bench.h"
#include "evaluation/exposure_bench.h"
#include "evaluation/fit_bench.h"
#include "evaluation/fit_sweeps_bench.h"
#include "evaluation/led_bench.h"
#include "evaluation/normals_bench.h"
#include "evaluation/rti_bench.h"
#include "evaluation/scale_bench.h"
#include "evaluation/sun_bench.h"
#include "evaluation/temporal_bench.h"
#include "lightstage/errors.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

RedrawnCharts redraw_bench_charts(const fs::path& dir) {
  if (const auto missing = chart_tool_missing()) throw InputError("bench charts: " + *missing);
  using Charts = void (*)(const fs::path&);
  const std::pair<const char*, Charts> benches[] = {
      {"leds.csv", write_led_charts},
      {"sun.csv", write_sun_charts},
      {"exposures.csv", write_exposure_chart},
      {"fit.csv", write_fit_charts},
      {"fit_sweeps.csv", write_fit_sweeps_charts},
      {"normals.csv", write_normals_chart},
      {"temporal.csv", write_temporal_charts},
      {"temporal_held_out.csv", write_temporal_held_out_chart},
      {"temporal_held_out_dark.csv", write_temporal_held_out_chart},
      {"compact.csv", write_compact_charts},
      {"rti.csv", write_rti_charts},
      {"scale.csv", write_scale_charts}};
  RedrawnCharts result;
  bool found = false;
  for (const auto& [name, charts] : benches) {
    if (!fs::exists(dir / name)) continue;
    found = true;
    try {
      charts(dir / name);
      result.drawn.push_back(dir / name);
    } catch (const InputError& e) {
      result.errors.emplace_back(e.what());
    }
  }
  if (!found) throw InputError(dir.string() + ": no bench CSV file (leds.csv, fit.csv, ...)");
  return result;
}

}  // namespace ls::evaluation
