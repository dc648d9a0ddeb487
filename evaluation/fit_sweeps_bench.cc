#include "evaluation/fit_sweeps_bench.h"

#include <algorithm>

#include "evaluation/chart.h"
#include "evaluation/csv_table.h"

namespace ls::evaluation {

void write_fit_sweeps_charts(const std::filesystem::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  const std::vector<std::string> axes = table.distinct("axis");
  for (const SweepAxis axis : kAllSweepAxes) {
    const std::string name = to_string(axis);
    if (std::find(axes.begin(), axes.end(), name) == axes.end()) continue;
    // Everything flagged leaves a point without an error (an empty field): not drawn.
    Chart chart{
        .csv = csv,
        .x = "value",
        .series = {{.title = "LS normals, mean", .y = "ls_mean_deg"},
                   {.title = "robust normals, mean", .y = "robust_mean_deg"},
                   {.title = "fit normals, mean",
                    .y = "fit_mean_deg",
                    .labels = {.column = "fit_flagged", .format = "%.0f%%", .scale = 100}},
                   {.title = "fit normals, p95", .y = "fit_p95_deg"}},
        .title = "Normal error vs " + std::string(axis_label(axis)) + " (labels: fit, % flagged)",
        .x_label = axis_label(axis),
        .y_label = "angular error of the normal, deg",
        .log_x = axis == SweepAxis::kLedCount};
    for (ChartSeries& s : chart.series) s.where = {{"axis", name}};
    write_chart(std::filesystem::path(csv).replace_filename("fit_sweeps_" + name + ".png"), chart);
  }
}

FitSweepsBenchSummary run_fit_sweeps_bench(const FitSweepsBenchOptions& options,
                                           const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  std::filesystem::create_directories(options.out);
  FitSweepOptions sweeps = options.sweeps;
  sweeps.progress = progress;
  FitSweepsBenchSummary summary;
  summary.points = run_fit_sweeps(sweeps);
  summary.csv = options.out / "fit_sweeps.csv";
  write_fit_sweeps_csv(summary.csv, summary.points);
  write_fit_sweeps_charts(summary.csv);
  for (const SweepPoint& p : summary.points) summary.invalid_outputs += p.invalid_outputs;
  return summary;
}

}  // namespace ls::evaluation
