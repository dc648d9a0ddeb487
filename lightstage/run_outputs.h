#pragma once
// What a run writes into an output folder, removed when the run fails: a run that fails for good
// leaves nothing behind. Destroyed before keep(), it removes the folder with all in it when the
// run made it (and the folders above it that it made too), else the files and folders it was told
// of (they may have replaced an earlier run's: what is left of that is no longer whole).
#include <filesystem>
#include <vector>

namespace ls {

// InputError naming the path when `folder`, or a folder above it, is there as a file: no folder
// can be made there (bad input, not a storage fault).
void require_folder_can_be_made(const std::filesystem::path& folder);

// InputError naming both when the output file `out` is (or resolves to: a link, another path to
// it) the input `input`: writing it would destroy what is being read.
void refuse_output_over_input(const std::filesystem::path& out, const std::filesystem::path& input);

class RunOutputs {
 public:
  // Notes whether `folder` is there already; it is made by whoever writes first. InputError
  // as require_folder_can_be_made's.
  explicit RunOutputs(std::filesystem::path folder);
  ~RunOutputs();
  RunOutputs(const RunOutputs&) = delete;
  RunOutputs& operator=(const RunOutputs&) = delete;

  // A file (or folder) about to be written (inside the folder or beside it).
  void add(const std::filesystem::path& file) { files_.push_back(file); }
  // The run succeeded: everything stays.
  void keep() { kept_ = true; }

 private:
  std::filesystem::path folder_;
  std::filesystem::path made_;  // The outermost folder missing at the start; empty: none.
  bool kept_ = false;
  std::vector<std::filesystem::path> files_;
};

}  // namespace ls
