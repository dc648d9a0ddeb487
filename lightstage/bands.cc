#include "lightstage/bands.h"

#include <algorithm>

namespace ls {

int rows_within(std::size_t budget_bytes, std::size_t row_bytes, int height, int alignment) {
  const std::size_t fitting = budget_bytes / std::max<std::size_t>(row_bytes, 1);
  if (fitting >= std::size_t(height)) return height;  // One band, starting on row 0: aligned.
  int rows = std::max(1, int(fitting));
  if (alignment > 1) rows = std::max(alignment, rows / alignment * alignment);
  return std::min(rows, height);
}

int band_rows_for_ranks(int rows, int height, int alignment, int ranks) {
  if (ranks == 1) return rows;
  // As many bands as the memory needs, at least kBandsPerRank a rank, and a multiple of the ranks
  // so that each rank takes as many (9 bands over 2 ranks kept one waiting a ninth of the work).
  constexpr int kBandsPerRank = 4;
  int bands = std::max((height + rows - 1) / rows, kBandsPerRank * ranks);
  bands = (bands + ranks - 1) / ranks * ranks;
  const int share = (height + bands - 1) / bands;
  const int aligned = (share + alignment - 1) / alignment * alignment;
  return std::max(alignment, std::min(rows, aligned));
}

BandPlan::BandPlan(int height, int rows) : height_(height), rows_(std::max(rows, 1)) {}

BandPlan BandPlan::within(const MemoryBudget& budget, std::size_t row_bytes, int height,
                          int alignment, const RankSplit& split) {
  const int rows = rows_within(budget.bytes(), row_bytes, height, alignment);
  return {height, band_rows_for_ranks(rows, height, std::max(alignment, 1), split.size)};
}

int BandPlan::end_row(int band) const { return std::min(height_, (band + 1) * rows_); }

long BandPlan::rows_mine(const RankSplit& split) const {
  long rows = 0;
  for_each_mine(split, [&](int, int y0, int y1) { rows += y1 - y0; });
  return rows;
}

void BandPlan::for_each_mine(const RankSplit& split,
                             const std::function<void(int band, int y0, int y1)>& visit) const {
  for (int b = 0; b < count(); ++b) {
    if (split.mine(b)) visit(b, first_row(b), end_row(b));
  }
}

int agreed_band_rows(const CheckpointDir& checkpoint, int proposed, const RankSplit& split) {
  const int rows = split.rank == 0 ? checkpoint.band_rows(proposed) : 0;
  if (!split.split()) return rows;
  split.barrier();  // Rank 0 decided before the others read it.
  return split.rank == 0 ? rows : checkpoint.recorded_rows();
}

}  // namespace ls
