#pragma once
// lightstage fit on a field read in bands of rows (--memory, and every run under MPI): normals and
// per-pixel fits band by band, each band kept in a checkpoint; then basis materials over more
// passes. Under MPI the bands are split over the ranks (Ranks::owns); rank 0 assembles the maps
// from the checkpoints and the ranks' assigned rows, and gets bytes identical to one process's.
#include "app/jobs/fit_checkpoint.h"
#include "app/jobs/job.h"
#include "app/jobs/ranks.h"
#include "capture/field.h"
#include "relight/fit/fit.h"

namespace ls::jobs {

struct BandFitTimes {
  double read_seconds = 0;  // Reading the field (not counted in the fit's time).
  int resumed_rows = 0;     // Rows whose fits an interrupted run had finished.
};

// The maps of the whole field on rank 0; on the other ranks, of their own bands only.
relight::ModelMaps fit_in_bands(capture::FieldStream& stream, int rows,
                                const relight::FitOptions& fit, const BandCheckpoints& checkpoints,
                                const Ranks& ranks, const ProgressFn& progress,
                                BandFitTimes& times);

// The band height for a fit split over `ranks` ranks (at most `rows`, from the memory budget):
// several bands a rank, so that round robin evens out bands that cost more (the object against
// the background), as many for each rank; whole tiles (`alignment` rows).
int band_rows_for_ranks(int rows, int height, int alignment, int ranks);

}  // namespace ls::jobs
