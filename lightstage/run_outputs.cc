#include "lightstage/run_outputs.h"

#include <utility>

namespace ls {

namespace fs = std::filesystem;

namespace {

// `folder` absolute and normal, without a trailing separator ("out/" names "out").
fs::path normal_folder(const fs::path& folder) {
  std::error_code ignored;
  fs::path normal = fs::absolute(folder, ignored).lexically_normal();
  if (!normal.has_filename()) normal = normal.parent_path();
  return normal;
}

// The outermost folder of `normal` that is missing (empty: none), and the nearest one there.
std::pair<fs::path, fs::path> missing_and_there(const fs::path& normal) {
  std::error_code ignored;
  fs::path missing, there = normal;
  while (!fs::exists(there, ignored) && there.parent_path() != there) {
    missing = there;
    there = there.parent_path();
  }
  return {missing, there};
}

}  // namespace

RunOutputs::RunOutputs(fs::path folder) : folder_(std::move(folder)) {
  made_ = missing_and_there(normal_folder(folder_)).first;
}

RunOutputs::~RunOutputs() {
  if (kept_) return;
  std::error_code ignored;
  if (!made_.empty()) {
    fs::remove_all(made_, ignored);
    return;
  }
  for (const fs::path& file : files_) fs::remove_all(file, ignored);
}

}  // namespace ls
