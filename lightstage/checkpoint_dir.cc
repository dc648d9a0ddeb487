#include "lightstage/checkpoint_dir.h"

#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <utility>

#include "lightstage/errors.h"
#include "lightstage/image.h"

namespace ls {

namespace fs = std::filesystem;

CheckpointDir::CheckpointDir(const fs::path& out, std::string identity)
    : dir_(out.string() + ".partial"), identity_(std::move(identity)) {}

namespace {

// CheckpointDir::left_for_resume(): the folders in use, by path.
std::mutex kept_mutex;
std::set<fs::path>& kept_dirs() {
  static std::set<fs::path> dirs;
  return dirs;
}

void keep(const fs::path& dir, bool kept) {
  const std::lock_guard lock(kept_mutex);
  if (kept) {
    kept_dirs().insert(dir);
  } else {
    kept_dirs().erase(dir);
  }
}

// The rows run.json records for `identity`, if it does.
std::optional<int> rows_recorded(const fs::path& dir, const std::string& identity) {
  try {
    std::ifstream in(dir / "run.json");
    const nlohmann::json j = nlohmann::json::parse(in);
    if (j.at("identity").get<std::string>() == identity) return j.at("rows").get<int>();
  } catch (const std::exception&) {  // None, unreadable or another run's.
  }
  return std::nullopt;
}

}  // namespace

int CheckpointDir::recorded_rows() const {
  if (const std::optional<int> rows = rows_recorded(dir_, identity_)) return *rows;
  throw InputError((dir_ / "run.json").string() +
                   ": not there for this rank, or another run's (does every node see the output's "
                   "folder, under the same path?)");
}

int CheckpointDir::band_rows(int proposed) const {
  if (const std::optional<int> rows = rows_recorded(dir_, identity_)) {
    keep(dir_, true);
    return *rows;
  }
  remove();  // None, unreadable or another run's: start afresh.
  keep(dir_, true);
  std::error_code error;
  fs::create_directories(dir_, error);
  if (error) {
    throw StorageError(dir_.string() +
                       ": cannot create the folder that lets a killed run resume (" +
                       error.message() + ")");
  }
  write_file_atomic(dir_ / "run.json",
                    nlohmann::json{{"identity", identity_}, {"rows", proposed}}.dump());
  return proposed;
}

std::string input_identity(const fs::path& input, const std::string& options_json) {
  std::error_code size_error, time_error;
  const auto size = fs::file_size(input, size_error);
  const auto time = fs::last_write_time(input, time_error).time_since_epoch().count();
  nlohmann::json options = nlohmann::json::parse(options_json);
  options.erase("memory_bytes");
  return nlohmann::json{{"field", fs::absolute(input).string()},
                        {"bytes", size_error ? 0 : size},
                        {"time", time_error ? 0 : time},
                        {"options", options}}
      .dump();
}

void write_record(const fs::path& file, const std::string& magic, const nlohmann::json& info,
                  const std::vector<RecordBytes>& blocks) {
  AtomicFileWriter out(file);
  const std::string header = magic + "\n" + info.dump() + "\n";
  out.write(header.data(), header.size());
  for (const RecordBytes& block : blocks) out.write(block.data, block.size);
  out.commit();
}

bool read_record(
    const fs::path& file, const std::string& magic,
    const std::function<std::optional<std::vector<RecordTarget>>(const nlohmann::json& info)>&
        place) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return false;
  std::vector<RecordTarget> targets;
  try {
    std::string line, header;
    if (!std::getline(in, line) || line != magic || !std::getline(in, header)) return false;
    std::optional<std::vector<RecordTarget>> placed = place(nlohmann::json::parse(header));
    if (!placed) return false;
    targets = std::move(*placed);
  } catch (const nlohmann::json::exception&) {
    return false;
  }
  for (const RecordTarget& target : targets) {
    if (!in.read(static_cast<char*>(target.data), std::streamsize(target.size))) return false;
  }
  return in.peek() == std::char_traits<char>::eof();  // Cut short or longer: done again.
}

void CheckpointDir::remove() const {
  std::error_code ignored;
  fs::remove_all(dir_, ignored);
  keep(dir_, false);
}

std::vector<fs::path> CheckpointDir::left_for_resume() {
  const std::lock_guard lock(kept_mutex);
  std::vector<fs::path> there;
  std::error_code ignored;
  for (const fs::path& dir : kept_dirs()) {
    if (!fs::is_directory(dir, ignored)) continue;
    if (fs::is_empty(dir, ignored)) {
      fs::remove(dir, ignored);
    } else {
      there.push_back(dir);
    }
  }
  return there;
}

}  // namespace ls
