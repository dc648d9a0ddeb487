#pragma once
// lightstage fit on a field read in bands of rows (--memory, and every run under MPI), never
// holding the maps whole: normals and per-pixel fits band by band, each band kept in a checkpoint;
// basis materials found from passes over the checkpoints and the field, assigned band by band
// into checkpoints of their own; the maps written from those a band at a time. Under MPI the bands
// are split over the ranks (round robin: neighbouring bands, which cost alike, go to different
// ranks) and rank 0 writes the maps from every rank's checkpoints: the same bytes as one process's.
#include <filesystem>
#include <vector>

#include "app/jobs/fit_checkpoint.h"
#include "app/jobs/job.h"
#include "app/jobs/ranks.h"
#include "capture/field.h"
#include "lightstage/image.h"
#include "relight/fit/fit.h"

namespace ls::jobs {

struct BandFitTimes {
  double read_seconds = 0;  // Reading the field (not counted in the fit's time).
  int resumed_rows = 0;     // Rows whose fits an interrupted run had finished.
};

// What the maps hold, on rank 0 (the other ranks' are empty).
struct BandFit {
  relight::FitSummary summary;
  std::vector<relight::Material> materials;
};

// Fits the field and, on rank 0, writes the maps to `out` with `attributes` in their header.
BandFit fit_in_bands(capture::FieldStream& stream, int rows, const relight::FitOptions& fit,
                     const BandCheckpoints& checkpoints, const Ranks& ranks,
                     const std::filesystem::path& out, const ExrAttributes& attributes,
                     const ProgressFn& progress, BandFitTimes& times);

// The band height for a fit split over `ranks` ranks (at most `rows`, from the memory budget):
// several bands a rank, so that round robin evens out bands that cost more (the object against
// the background), as many for each rank; whole tiles (`alignment` rows).
int band_rows_for_ranks(int rows, int height, int alignment, int ranks);

}  // namespace ls::jobs
