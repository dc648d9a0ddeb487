#pragma once
// Work split over the processes of an MPI run (app/jobs/ranks.h) for the libraries, which do not
// know MPI: this process is `rank` of `size`, takes the items i with i % size == rank (round robin:
// neighbouring items, which cost alike, go to different ranks), and waits for the others at
// `barrier`. The default is one process doing everything.
#include <functional>

namespace ls {

struct RankSplit {
  int rank = 0, size = 1;
  std::function<void()> barrier;
  bool split() const { return size > 1; }
  bool mine(int item) const { return item % size == rank; }
};

}  // namespace ls
