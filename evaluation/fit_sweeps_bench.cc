#include "evaluation/fit_sweeps_bench.h"

#include <cstdio>
#include <limits>
#include <optional>

#include "evaluation/chart.h"

namespace ls::evaluation {

namespace {

void write_axis_chart(const std::filesystem::path& out, SweepAxis axis,
                      const std::vector<SweepPoint>& points) {
  std::vector<ChartSeries> series(4);
  series[0].name = "LS normals, mean";
  series[1].name = "robust normals, mean";
  series[2].name = "fit normals, mean";
  series[3].name = "fit normals, p95";
  for (const SweepPoint& p : points) {
    if (p.axis != axis) continue;
    const std::optional<double>* y[4] = {&p.least_squares.mean_deg, &p.robust.mean_deg,
                                         &p.fit.mean_deg, &p.fit.p95_deg};
    for (int k = 0; k < 4; ++k) {
      // Everything flagged: no error to plot (the chart skips non-finite points).
      series[k].x.push_back(p.value);
      series[k].y.push_back(y[k]->value_or(std::numeric_limits<double>::quiet_NaN()));
    }
    char label[48];
    std::snprintf(label, sizeof label, "%.0f%% flagged", 100 * p.fit.flagged_fraction);
    series[2].point_labels.push_back(label);
  }
  write_chart(out / ("fit_sweeps_" + std::string(to_string(axis)) + ".png"),
              {"Normal error vs " + std::string(axis_label(axis)) + " (labels: fit, % flagged)",
               axis_label(axis), "angular error of the normal, deg", axis == SweepAxis::kLedCount},
              series);
}

}  // namespace

FitSweepsBenchSummary run_fit_sweeps_bench(const FitSweepsBenchOptions& options,
                                           const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  std::filesystem::create_directories(options.out);
  FitSweepOptions sweeps = options.sweeps;
  sweeps.on_progress = [&](int done, int total) { report(progress, "fit sweeps", done, total); };
  FitSweepsBenchSummary summary;
  summary.points = run_fit_sweeps(sweeps);
  summary.csv = options.out / "fit_sweeps.csv";
  write_fit_sweeps_csv(summary.csv, summary.points);
  for (const SweepAxis axis : sweeps.axes) write_axis_chart(options.out, axis, summary.points);
  for (const SweepPoint& p : summary.points) summary.invalid_outputs += p.invalid_outputs;
  return summary;
}

}  // namespace ls::evaluation
