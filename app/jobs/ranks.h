#pragma once
// The processes of a run under MPI (mpirun, or srun under Slurm): `lightstage fit` splits its bands
// of rows over them. Without MPI, or started without a launcher, there is one process,
// rank 0, and every call below is trivial. Built with MPI when CMake finds it (find_package(MPI)).
#include <vector>

#include "lightstage/rank_split.h"

namespace ls::jobs {

class Ranks {
 public:
  // The run's processes: MPI's world when this process was started by an MPI launcher.
  static Ranks& world();

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool root() const { return rank_ == 0; }

  void barrier() const;
  // Rank 0's values, on every rank (resized to rank 0's size).
  void broadcast(std::vector<double>& values) const;
  // The libraries' view of these processes (lightstage/rank_split.h); refers to *this.
  RankSplit split() const;
  // Ends every rank's process with `exit_code`: one rank's error must not leave the others waiting.
  [[noreturn]] void abort(int exit_code) const;

  // Starts MPI when this process was started by an MPI launcher (main's first statement), and
  // ends it; throws InputError when launched so but built without MPI.
  class Session {
   public:
    Session(int& argc, char**& argv);
    ~Session();
    Session(const Session&) = delete;
    Session& operator=(const Session&) = delete;
  };

 private:
  int rank_ = 0;
  int size_ = 1;
};

}  // namespace ls::jobs
