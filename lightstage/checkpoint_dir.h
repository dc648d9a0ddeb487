#pragma once
// A folder beside a long job's output (OUT.partial/) where it keeps what it has finished until the
// output is written, so that a run that is killed resumes from it (issue 14: fit's bands, build's
// merged LEDs). run.json records the run's identity (what must match for the folder's contents to
// be reused: input, its size and time, options) and its band height.
#include <filesystem>
#include <string>

namespace ls {

class CheckpointDir {
 public:
  CheckpointDir(const std::filesystem::path& out, std::string identity);
  // The band height to run with: an earlier run's with the same identity, so that what it left is
  // reused; otherwise `proposed`, recorded for a later run (an earlier run's contents are dropped).
  int band_rows(int proposed) const;
  const std::filesystem::path& dir() const { return dir_; }
  // Once the output is written.
  void remove() const;

 private:
  std::filesystem::path dir_;
  std::string identity_;
};

// The identity of a run over the file `input` with these options (a JSON object; its
// "memory_bytes" left out: the budget only sets the band height, which run.json records): the
// file's absolute path, size and modification time, and the options.
std::string input_identity(const std::filesystem::path& input, const std::string& options_json);

}  // namespace ls
