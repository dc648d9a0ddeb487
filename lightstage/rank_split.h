#pragma once
// Work split over the processes of an MPI run (app/jobs/ranks.h: Ranks::split) for the libraries,
// which do not know MPI: this process is `rank` of `size`, takes the items i with i % size == rank
// (round robin: neighbouring items, which cost alike, go to different ranks), waits for the others
// at `barrier` and gets rank 0's values by `broadcast`. The default is one process doing
// everything; lightstage/bands.h plans bands of rows over it.
#include <functional>
#include <vector>

namespace ls {

struct RankSplit {
  int rank = 0, size = 1;
  std::function<void()> barrier;
  // Rank 0's values on every rank (resized to rank 0's size).
  std::function<void(std::vector<double>& values)> broadcast;

  bool split() const { return size > 1; }
  bool root() const { return rank == 0; }
  bool mine(int item) const { return item % size == rank; }
  // barrier and broadcast, for one process nothing.
  void wait() const {
    if (split()) barrier();
  }
  void share(std::vector<double>& values) const {
    if (split()) broadcast(values);
  }
};

}  // namespace ls
