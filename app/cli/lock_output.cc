// The lock a command holds on its output while it writes it (lightstage/output_lock.h).
#include "app/cli/commands.h"
#include "app/jobs/ranks.h"

namespace ls::cli {

std::unique_ptr<OutputLock> lock_output(const std::filesystem::path& out) {
  if (!jobs::Ranks::world().root()) return nullptr;  // Under MPI rank 0 holds it for all.
  return std::make_unique<OutputLock>(out);
}

}  // namespace ls::cli
