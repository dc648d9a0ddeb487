#pragma once
// Execution over bands of rows and the processes of a run, for every job that holds a field's data
// within a memory budget (lightstage/memory.h: what each command's budget bounds): the rows a band
// takes, the bands this process takes (RankSplit: MPI stays in the app), and the band height the
// processes and a resumed run agree on (CheckpointDir).
#include <cstddef>
#include <functional>

#include "lightstage/checkpoint_dir.h"
#include "lightstage/memory.h"
#include "lightstage/rank_split.h"

namespace ls {

// The rows of a band within `budget_bytes` at `row_bytes` a row (every copy of a row the work
// holds counted): the height when they all fit, else at least one; with `alignment` > 1 (a tiled
// file's tile height) a multiple of it, at least one tile, unless that is more than the height.
int rows_within(std::size_t budget_bytes, std::size_t row_bytes, int height, int alignment = 1);

// The band height for work split over `ranks` processes (at most `rows`, from the budget):
// several bands a rank, so that round robin evens out bands that cost more (the object against
// the background), as many for each rank; whole tiles (`alignment` rows). `rows` for one rank.
int band_rows_for_ranks(int rows, int height, int alignment, int ranks);

// Rows [0, height) in bands of rows() rows (the last one shorter).
class BandPlan {
 public:
  BandPlan(int height, int rows);
  // Within `budget` at `row_bytes` a row (rows_within), whole `alignment` rows, and several bands
  // a rank under a split (band_rows_for_ranks).
  static BandPlan within(const MemoryBudget& budget, std::size_t row_bytes, int height,
                         int alignment = 1, const RankSplit& split = {});

  int height() const { return height_; }
  int rows() const { return rows_; }
  bool whole() const { return rows_ >= height_; }
  int count() const { return (height_ + rows_ - 1) / rows_; }
  int first_row(int band) const { return band * rows_; }
  int end_row(int band) const;
  // Rows of the bands this process takes (split.mine(band)), together.
  long rows_mine(const RankSplit& split) const;
  // Rows [y0, y1) of each band this process takes (split.mine(band)), in order.
  void for_each_mine(const RankSplit& split,
                     const std::function<void(int band, int y0, int y1)>& visit) const;

 private:
  int height_, rows_;
};

// The band height every process of a run, and a later run resuming it, works in: rank 0 takes the
// height `checkpoint` records for this run (or records `proposed`), the others wait for it at
// split.barrier and read it back (the folder must be seen by every process).
int agreed_band_rows(const CheckpointDir& checkpoint, int proposed, const RankSplit& split);

}  // namespace ls
