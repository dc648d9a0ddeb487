#pragma once
// A PCA (pca_field.h) of a field read in bands of rows (lightstage/bands.h), never holding its
// coefficients: the basis from passes over the bands (kept in the checkpoint: a rerun skips those
// passes), then each band's coefficients into a spill in the checkpoint (kept, with a record per
// band: a rerun projects only the bands not there), then the file written from the spill. Split
// over ranks (RankSplit), every rank makes the grams and coefficients of its own bands; rank 0
// finds the basis and writes the file (the others return once their bands are in). The same
// bytes as PcaField::build and write of the whole field.
#include <filesystem>
#include <functional>

#include "capture/field.h"
#include "lightstage/checkpoint_dir.h"
#include "lightstage/progress.h"
#include "lightstage/rank_split.h"
#include "relight/compact/pca_field.h"

namespace ls::relight {

struct PcaBandsInput {
  const capture::ReflectanceField& header;  // The field's lights and size, no values.
  // Rows [y0, y1) of the field into `band`.
  std::function<void(int y0, int y1, capture::ReflectanceField& band)> read_rows;
  const capture::FieldBands& bands;  // Every band of `rows` rows, in order (the basis passes).
  int rows = 0;                      // Band height (whole PcaField::band_alignment sub-bands).
};

// Writes the PCA of `input` to `out`; returns its basis. `resumed_rows`: rows a killed run had
// projected; progress "coefficients (rows)" after each of this rank's bands ("resumed" for one a
// killed run had done).
PcaField pca_in_bands(const PcaBandsInput& input, const PcaOptions& options,
                      const CheckpointDir& checkpoint, const std::filesystem::path& out,
                      const RankSplit& split, PcaSummary& summary, int& resumed_rows,
                      const ProgressFn& progress = {});

}  // namespace ls::relight
