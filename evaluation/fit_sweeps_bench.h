#pragma once
// `lightstage bench fit-sweeps`: the failure sweeps of evaluation/fit_sweeps.h written as
// fit_sweeps.csv and one chart per axis, fit_sweeps_<axis>.png (normal error against the axis,
// the fit's flagged fraction as point labels).
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"
#include "evaluation/fit_sweeps.h"

namespace ls::evaluation {

struct FitSweepsBenchOptions {
  std::filesystem::path out = "bench-out";
  FitSweepOptions sweeps;  // progress is set by the bench.
  std::string validate() const { return sweeps.validate(); }
};

struct FitSweepsBenchSummary {
  std::vector<SweepPoint> points;
  int invalid_outputs = 0;    // Over all points; must be 0.
  std::filesystem::path csv;  // fit_sweeps.csv; the charts beside it.
};

FitSweepsBenchSummary run_fit_sweeps_bench(const FitSweepsBenchOptions& options,
                                           const ProgressFn& progress = {});

// fit_sweeps_<axis>.png, one per axis in `csv` (a fit_sweeps.csv), beside it, from it alone.
void write_fit_sweeps_charts(const std::filesystem::path& csv);

}  // namespace ls::evaluation
