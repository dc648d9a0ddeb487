#pragma once
// A folder beside a long job's output (OUT.partial/) where it keeps what it has finished until the
// output is written, so that a run that is killed resumes from it (fit's bands, build's
// merged LEDs). run.json records the run's identity (what must match for the folder's contents to
// be reused: input, its size and time, options) and its band height.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace ls {

class CheckpointDir {
 public:
  CheckpointDir(const std::filesystem::path& out, std::string identity);
  // The band height to run with: an earlier run's with the same identity, so that what it left is
  // reused; otherwise `proposed`, recorded for a later run (an earlier run's contents are dropped).
  int band_rows(int proposed) const;
  // The band height the folder records for this identity, without touching it (the other ranks
  // of an MPI run, after rank 0's band_rows): InputError when it records none (an output folder
  // that every node does not see?).
  int recorded_rows() const;
  const std::filesystem::path& dir() const { return dir_; }
  // Once the output is written.
  void remove() const;
  // After a run failed: the folders this process made or reused (band_rows()) and did not remove,
  // where they still are and hold something, for the next run to resume from (the CLI names them);
  // those holding nothing are removed.
  static std::vector<std::filesystem::path> left_for_resume();

 private:
  std::filesystem::path dir_;
  std::string identity_;
};

// A checkpoint record: a magic line, a line of JSON (what the bytes are), then raw bytes (exact
// values; a checkpoint lives for one run and is read back by this program only), written
// atomically: there whole or not at all.
struct RecordBytes {
  const void* data;
  std::size_t size;
};
void write_record(const std::filesystem::path& file, const std::string& magic,
                  const nlohmann::json& info, const std::vector<RecordBytes>& blocks);
// Reads a record: `place(info)` says where its bytes go, or nullopt (or throws nlohmann's
// exceptions) for an info it cannot use. False when the file is missing, of another magic, or its
// info or bytes are not what `place` asked for: what it held is done again.
struct RecordTarget {
  void* data;
  std::size_t size;
};
bool read_record(
    const std::filesystem::path& file, const std::string& magic,
    const std::function<std::optional<std::vector<RecordTarget>>(const nlohmann::json& info)>&
        place);

// The identity of a run over the file `input` with these options (a JSON object; its
// "memory_bytes" left out: the budget only sets the band height, which run.json records): the
// file's absolute path, size and modification time, and the options.
std::string input_identity(const std::filesystem::path& input, const std::string& options_json);

}  // namespace ls
