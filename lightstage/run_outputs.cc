#include "lightstage/run_outputs.h"

#include <utility>

namespace ls {

namespace fs = std::filesystem;

RunOutputs::RunOutputs(fs::path folder) : folder_(std::move(folder)) {
  std::error_code ignored;
  folder_existed_ = fs::exists(folder_, ignored);
}

RunOutputs::~RunOutputs() {
  if (kept_) return;
  std::error_code ignored;
  if (!folder_existed_) {
    fs::remove_all(folder_, ignored);
    return;
  }
  for (const fs::path& file : files_) fs::remove(file, ignored);
}

}  // namespace ls
