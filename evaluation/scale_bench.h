#pragma once
// lightstage bench scale: each step of the pipeline on captures of growing size, run
// as the user runs it (the lightstage executable, one process per step) within a memory budget:
// wall time, peak resident memory (the process's own, from wait4) against the budget, and reading
// the field's bytes from the page cache and from disk in the same run, for comparison with
// relighting, which reads them once. Fits under MPI with 1 and 2 ranks, and a model of fit time
// against ranks from them. The capture is the simulated stage's (every shadow ray traced): it is
// timed but not repeated.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"

namespace ls::evaluation {

struct ScaleBenchOptions {
  std::filesystem::path out = "bench-out/scale";
  std::filesystem::path executable;   // The lightstage executable (the CLI: itself).
  std::filesystem::path env_map;      // Relit under (the CLI: a shipped map).
  std::vector<int> sizes{512, 1024};  // Camera width = height.
  int runs = 3;                       // Each step's repeats (medians reported).
  std::size_t memory_bytes = std::size_t(256) << 20;  // --memory of every step.
  // Larger fields are not fitted: a fit's time grows with the pixels (about 5 minutes a run at
  // 4096² on 2 cores), and fits and MPI runs happen at every size up to it.
  int fit_max_size = 1024;
  // 1 and 2 ranks at the largest fitted size (the nearest to a real capture), when mpiexec is on
  // PATH.
  bool mpi = true;
  bool keep = false;  // Keep the sessions and fields (otherwise removed after each size).
  // One exposure (the bracket's middle one) instead of the dome's three: a third of the frames'
  // disk and capture time, for the largest sizes.
  bool single_exposure = false;
  std::string validate() const;
};

struct ScaleBenchRow {
  int size = 0;  // Camera width = height.
  int leds = 0;
  std::string step;      // capture, build, read (cache), read (disk), relight (cache), ...
  double seconds = 0;    // Median over the runs.
  double peak_mib = 0;   // Peak resident memory of the step's process (median); 0 for reads.
  double field_mib = 0;  // The field file's size.
  double per_unit = 0;   // Seconds per frame (build: per LED image; relight: per relit image),
                         // or pixels per second (fit), or MB/s (reads, compress).
  std::string unit;
};

// Fit time against ranks: measured with 1 and 2 (each rank one core), and T(n) = s + p / n with
// the serial part s and parallel part p from those two, floored by the field's passes read from a
// store as fast as this machine's disk.
struct ScaleMpiModel {
  double one_rank_s = 0, two_ranks_s = 0, serial_s = 0, parallel_s = 0, io_floor_s = 0;
  std::vector<int> ranks;
  std::vector<double> model_s;
};

struct ScaleBenchSummary {
  std::vector<ScaleBenchRow> rows;
  ScaleMpiModel mpi;          // Empty (ranks empty) when not run.
  int mpi_size = 0;           // The size it was measured at.
  std::string mpi_note;       // Why MPI was not measured.
  std::filesystem::path csv;  // scale.csv; scale_*.png beside it.
};

ScaleBenchSummary run_scale_bench(const ScaleBenchOptions& options, const ProgressFn& progress);

// From `csv` (a scale.csv, one row per run): scale_medians.csv (per size and step, the medians
// over the runs) and, when MPI fits ran, scale_mpi.csv (the model of fit time against ranks)
// beside it, and the charts from those: scale_peak_memory.png, scale_throughput.png,
// scale_mpi_ranks.png.
void write_scale_charts(const std::filesystem::path& csv);

}  // namespace ls::evaluation
