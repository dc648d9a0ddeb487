#include "app/jobs/ranks.h"

#include <cstdlib>
#include <string>

#include "lightstage/errors.h"

#if LIGHTSTAGE_HAVE_MPI
#include <mpi.h>
#endif

namespace ls::jobs {

namespace {

// Set by the launchers: Open MPI's mpirun, and PMI/PMIx (MPICH, Slurm's srun).
bool started_by_mpi_launcher() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"}) {
    if (std::getenv(name) != nullptr) return true;
  }
  return false;
}

}  // namespace

Ranks& Ranks::world() {
  static Ranks ranks;
  return ranks;
}

RankSplit Ranks::split() const {
  return {rank_, size_, [this] { barrier(); },
          [this](std::vector<double>& values) { broadcast(values); }};
}

#if LIGHTSTAGE_HAVE_MPI

namespace {
bool mpi_started = false;
}  // namespace

Ranks::Session::Session(int& argc, char**& argv) {
  if (!started_by_mpi_launcher()) return;
  MPI_Init(&argc, &argv);
  mpi_started = true;
  Ranks& ranks = world();
  MPI_Comm_rank(MPI_COMM_WORLD, &ranks.rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks.size_);
}

Ranks::Session::~Session() {
  if (mpi_started) MPI_Finalize();
}

void Ranks::barrier() const {
  if (size_ > 1) MPI_Barrier(MPI_COMM_WORLD);
}

void Ranks::broadcast(std::vector<double>& values) const {
  if (size_ == 1) return;
  unsigned long long count = values.size();
  MPI_Bcast(&count, 1, MPI_UNSIGNED_LONG_LONG, 0, MPI_COMM_WORLD);
  values.resize(count);
  MPI_Bcast(values.data(), int(count), MPI_DOUBLE, 0, MPI_COMM_WORLD);
}

void Ranks::abort(int exit_code) const {
  if (mpi_started) MPI_Abort(MPI_COMM_WORLD, exit_code);
  std::exit(exit_code);
}

#else  // One process.

Ranks::Session::Session(int&, char**&) {
  if (started_by_mpi_launcher()) {
    throw InputError(
        "started by an MPI launcher, but this lightstage was built without MPI: install "
        "libopenmpi-dev (scripts/setup.sh does) and build again, or run it as one process");
  }
}

Ranks::Session::~Session() = default;
void Ranks::barrier() const {}
void Ranks::broadcast(std::vector<double>&) const {}
void Ranks::abort(int exit_code) const { std::exit(exit_code); }

#endif

}  // namespace ls::jobs
