#pragma once
// The temporal fit (temporal_fit.h) of time-step fields read in bands of rows (lightstage/bands.h:
// fit --time --memory, and every run split over processes), never holding a field or the maps
// whole. Everything in a temporal fit is per pixel but its data-driven curves, which are learnt
// from a sample of the whole image, so:
//   1. per band: normals (from the source step's band), each step's BRDF fit and each pixel's
//      process, kept in a checkpoint (OUT.partial/steps_Y.band);
//   2. rank 0 counts the pixels no process explains over every checkpoint, gathers its strided
//      sample from them in a second pass, learns the curves and sends them to every rank;
//   3. per band: the curves offered to its pixels, kept in a second checkpoint (curves_Y.band);
//   4. rank 0 writes the maps from those a band at a time.
// The same bytes as the fit of the whole fields (relight::fit_temporal); under MPI the bands are
// split over the ranks round robin (RankSplit); a killed run resumes from the bands its checkpoints
// hold.
#include <filesystem>
#include <memory>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/checkpoint_dir.h"
#include "lightstage/image.h"
#include "lightstage/progress.h"
#include "lightstage/rank_split.h"
#include "relight/time/temporal_fit.h"

namespace ls::relight {

struct TimeBandFit {
  relight::TemporalSummary summary;  // Rank 0's (the others': their own bands' counts).
  int resumed_rows = 0;              // Rows this rank took from an interrupted run.
};

// `steps`: one open field per time step, sorted by scene time, of the same size and lights.
TimeBandFit fit_over_time_in_bands(const std::vector<std::unique_ptr<capture::FieldStream>>& steps,
                                   int rows, const relight::TemporalFitOptions& fit,
                                   const CheckpointDir& checkpoints, const RankSplit& split,
                                   const std::filesystem::path& out,
                                   const ExrAttributes& attributes, const ProgressFn& progress);

// The bytes a band row of the fit takes: every step's field row (as read, with its reader's
// buffer; twice for pooled normals), every step's fit of the row, the maps and the normals' fit.
std::size_t time_band_row_bytes(const capture::FieldStream& step, int steps,
                                relight::NormalSource source);

}  // namespace ls::relight
