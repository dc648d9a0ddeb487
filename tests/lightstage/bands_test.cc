// Bands of rows within a memory budget and over the processes of a run (lightstage/bands.h).
#include "lightstage/bands.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "tests/support/test_support.h"

namespace ls {
namespace {

TEST(BandPlan, RowsWithinABudget) {
  // 1000 bytes a row, 100 rows.
  EXPECT_EQ(rows_within(100000, 1000, 100), 100);  // All fit: whole.
  EXPECT_EQ(rows_within(1 << 30, 1000, 100), 100);
  EXPECT_EQ(rows_within(25999, 1000, 100), 25);
  EXPECT_EQ(rows_within(999, 1000, 100), 1);  // At least a row, whatever the budget.
  EXPECT_EQ(rows_within(0, 1000, 100), 1);
  // Whole tiles of 16 rows, at least one; the whole height when it all fits.
  EXPECT_EQ(rows_within(40000, 1000, 100, 16), 32);
  EXPECT_EQ(rows_within(5000, 1000, 100, 16), 16);
  EXPECT_EQ(rows_within(99000, 1000, 100, 16), 96);
  EXPECT_EQ(rows_within(100000, 1000, 100, 16), 100);
  EXPECT_EQ(rows_within(5000, 1000, 10, 16), 10);  // A tile taller than the field.

  const BandPlan plan = BandPlan::within(MemoryBudget(25999), 1000, 100);
  EXPECT_EQ(plan.rows(), 25);
  EXPECT_EQ(plan.count(), 4);
  EXPECT_FALSE(plan.whole());
  EXPECT_EQ(plan.first_row(3), 75);
  EXPECT_EQ(plan.end_row(3), 100);
  const BandPlan uneven(100, 30);
  EXPECT_EQ(uneven.count(), 4);
  EXPECT_EQ(uneven.end_row(3), 100);  // The last band shorter.
  EXPECT_TRUE(BandPlan::within(MemoryBudget(1 << 20), 1000, 100).whole());
  // Unset: half of the memory available, which holds these 100 KB.
  EXPECT_TRUE(BandPlan::within(MemoryBudget(), 1000, 100).whole());
}

// Every rank takes about as many rows (9 bands of 115 rows over 2 ranks left one idle a ninth of
// the work), in at least 4 bands a rank, within the budget's band height and whole tiles.
TEST(BandPlan, EveryRankGetsAsManyRows) {
  constexpr int kHeight = 1024;
  for (const int ranks : {2, 3, 8}) {
    for (const int memory_rows : {7, 115, 1024}) {
      const int rows = band_rows_for_ranks(memory_rows, kHeight, 1, ranks);
      EXPECT_LE(rows, memory_rows);
      std::vector<int> per_rank(size_t(ranks), 0);
      const BandPlan plan(kHeight, rows);
      for (int rank = 0; rank < ranks; ++rank) {
        plan.for_each_mine({rank, ranks}, [&](int band, int y0, int y1) {
          EXPECT_EQ(band % ranks, rank);
          per_rank[size_t(rank)] += y1 - y0;
        });
      }
      EXPECT_GE(plan.count(), 4 * ranks);
      const auto [fewest, most] = std::minmax_element(per_rank.begin(), per_rank.end());
      EXPECT_LE(*most - *fewest, rows) << ranks << " ranks, " << memory_rows << " rows";
      int all = 0;
      for (const int r : per_rank) all += r;
      EXPECT_EQ(all, kHeight);  // Every row, once.
    }
  }
  // 10 bands of 103 rows (515 and 509 rows a rank), not 9 of 115 (575 and 460).
  EXPECT_EQ(band_rows_for_ranks(115, kHeight, 1, 2), 103);
  EXPECT_EQ(band_rows_for_ranks(115, kHeight, 16, 2) % 16, 0);
  EXPECT_EQ(band_rows_for_ranks(115, kHeight, 1, 1), 115);
  // A plan within a budget, split: the budget's rows, then as many for each rank.
  const BandPlan split = BandPlan::within(MemoryBudget(115 * 1000), 1000, kHeight, 1, {0, 2});
  EXPECT_EQ(split.rows(), 103);
}

// The band height a resumed run takes: the one its checkpoint recorded, whatever it proposes now.
TEST(BandPlan, AgreedRowsAreTheCheckpointsOnes) {
  testing::TempDir dir;
  const CheckpointDir checkpoint(dir / "out.exr", "run 1");
  EXPECT_EQ(agreed_band_rows(checkpoint, 12, {}), 12);
  EXPECT_EQ(agreed_band_rows(checkpoint, 40, {}), 12);  // A rerun: the recorded height.
  EXPECT_EQ(checkpoint.recorded_rows(), 12);
  const CheckpointDir other(dir / "out.exr", "run 2");  // Another run's: started afresh.
  EXPECT_EQ(agreed_band_rows(other, 40, {}), 40);
  // A second rank of a split reads rank 0's after the barrier.
  int waits = 0;
  const RankSplit second{1, 2, [&] { ++waits; }, {}};
  EXPECT_EQ(agreed_band_rows(other, 7, second), 40);
  EXPECT_EQ(waits, 1);
}

}  // namespace
}  // namespace ls
