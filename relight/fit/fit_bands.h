#pragma once
// Fitting a field read in bands of rows (lightstage/bands.h: fit --memory, and every run split over
// processes), never
// holding the maps whole: normals and per-pixel fits band by band, each band kept in a checkpoint;
// basis materials found from passes over the checkpoints and the field, assigned band by band
// into checkpoints of their own; the maps written from those a band at a time. Split (RankSplit),
// the bands go to the ranks (round robin: neighbouring bands, which cost alike, go to different
// ranks) and rank 0 writes the maps from every rank's checkpoints: the same bytes as one process's.
#include <filesystem>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/image.h"
#include "lightstage/progress.h"
#include "lightstage/rank_split.h"
#include "relight/fit/fit.h"
#include "relight/fit/fit_checkpoint.h"

namespace ls::relight {

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
                     const BandCheckpoints& checkpoints, const RankSplit& split,
                     const std::filesystem::path& out, const ExrAttributes& attributes,
                     const ProgressFn& progress, BandFitTimes& times);

}  // namespace ls::relight
