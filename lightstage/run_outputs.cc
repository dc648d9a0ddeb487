#include "lightstage/run_outputs.h"

#include <utility>

#include "lightstage/errors.h"

namespace ls {

namespace fs = std::filesystem;

void refuse_output_over_input(const fs::path& out, const fs::path& input) {
  std::error_code ignored;
  if (fs::exists(out, ignored) && fs::equivalent(out, input, ignored)) {
    throw InputError(out.string() + ": --out is the input " + input.string() +
                     ": writing it would destroy what is read; give another output file");
  }
}

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

void require_folder_can_be_made(const fs::path& folder) {
  const fs::path normal = normal_folder(folder);
  const fs::path there = missing_and_there(normal).second;
  std::error_code ignored;
  if (!fs::is_directory(there, ignored)) {  // Said before a write fails on it.
    throw InputError((there == normal ? folder : there).string() +
                     ": expected a folder to write into, found a file");
  }
}

RunOutputs::RunOutputs(fs::path folder) : folder_(std::move(folder)) {
  require_folder_can_be_made(folder_);
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
