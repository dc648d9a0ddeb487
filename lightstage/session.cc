#include "lightstage/session.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "lightstage/errors.h"
#include "lightstage/json_reader.h"
#include "lightstage/run_outputs.h"

namespace ls {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kManifest = "manifest.json";
constexpr const char* kJournal = "frames.jsonl";
constexpr const char* kFormat = "lightstage-session/1";

std::string utc_now_iso8601() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, int(ms));
  return buf;
}

std::string read_text(const fs::path& path) {
  // A folder opens as an empty stream on Linux: say what it is, not "invalid JSON".
  if (fs::is_directory(path)) throw InputError(path.string() + ": expected a file, found a folder");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open");
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The integers of a journal line, checked against the session's plan: an index beyond it (or
// beyond an int) would reach past the stage's LEDs, steps or exposures.
struct JournalLine {
  const json& j;
  std::string where;  // "SESSION/frames.jsonl:N"
  const Stage& stage;

  int int_in(const char* key, int lo, int hi) const {
    const json& v = j.at(key);
    // An unsigned beyond int64 is out of range whatever the plan: not converted.
    const bool fits = v.is_number_integer() &&
                      !(v.is_number_unsigned() &&
                        v.get<uint64_t>() > uint64_t(std::numeric_limits<int64_t>::max()));
    if (!fits || v.get<int64_t>() < lo || v.get<int64_t>() > hi) {
      throw InputError(where + ": " + key + ": expected an integer in [" + std::to_string(lo) +
                       ", " + std::to_string(hi) + "] (the session's plan), got " + v.dump());
    }
    return int(v.get<int64_t>());
  }
  // A non-negative integer at most `hi` (a size or a checksum); a float, a negative or a larger
  // number is refused before any conversion.
  uint64_t unsigned_at_most(const char* key, uint64_t hi) const {
    const json& v = j.at(key);
    if (!v.is_number_unsigned() || v.get<uint64_t>() > hi) {
      throw InputError(where + ": " + key + ": expected an integer in [0, " + std::to_string(hi) +
                       "], got " + v.dump());
    }
    return v.get<uint64_t>();
  }
  int step(const char* key) const { return int_in(key, 0, stage.plan.time_steps - 1); }
  int led(const char* key) const { return int_in(key, 0, int(stage.leds.size()) - 1); }
};

// A write killed mid-way leaves its temporary file (never journaled, so never a frame): removed.
void sweep_temporary_frames(const fs::path& dir) {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir / "frames", ec)) {
    if (entry.path().filename().string().find(".tmp") != std::string::npos) {
      fs::remove(entry.path(), ec);
    }
  }
}

// The journal's text as read (empty when there is none). A torn last line (killed mid-append) is
// cut off the file, so that the next append starts on a line of its own.
std::string read_journal(const fs::path& journal_path) {
  std::string text = fs::exists(journal_path) ? read_text(journal_path) : "";
  if (text.empty() || text.back() == '\n') return text;
  std::cerr << "warning: " << journal_path.string()
            << ": incomplete last journal line ignored (interrupted write); that frame will be "
               "captured again\n";
  const size_t complete = text.rfind('\n');
  std::error_code ec;
  fs::resize_file(journal_path, complete == std::string::npos ? 0 : complete + 1, ec);
  if (ec)
    throw StorageError(journal_path.string() + ": cannot cut the torn last line: " + ec.message());
  return text;
}

// Journal line `line_no` as JSON; none (with a warning) when it is not JSON at all.
std::optional<json> parse_journal_line(const std::string& line, const fs::path& journal_path,
                                       int line_no) {
  try {
    return json::parse(line);
  } catch (const json::parse_error&) {
    // Not a torn write (only the last line can be one, and it was cut): damage.
    std::cerr << "warning: " << journal_path.string() << ":" << line_no
              << ": not a journal record (the journal is damaged here; a write cut short can "
                 "only be the last line): ignored; the frame it named, if any, will be "
                 "captured again\n";
    return std::nullopt;
  } catch (const json::exception& e) {  // E.g. a number beyond a double.
    throw InputError(journal_path.string() + ":" + std::to_string(line_no) +
                     ": not a journal line: " + e.what());
  }
}

// The frame a journal line `j` records (`in` checks its integers); none (with a warning) when its
// file is missing on disk.
std::optional<FrameRecord> read_frame_record(json& j, const JournalLine& in, const FrameKey& key,
                                             const fs::path& dir) {
  FrameRecord rec;
  rec.key = key;
  rec.file = j["file"].get<std::string>();
  rec.exposure_s = j["exposure_s"].get<double>();
  rec.gain = j["gain"].get<double>();
  rec.scene_time_s = j["scene_time_s"].get<double>();
  rec.captured_at = j["at"].get<std::string>();
  if (j.contains("timing")) {
    const json& t = j["timing"];
    rec.timing = {t.value("led_on_ns", int64_t(0)), t.value("requested_ns", int64_t(0)),
                  t.value("delivered_ns", int64_t(0)), t.value("led_off_ns", int64_t(0)),
                  t.value("sensor_ns", uint64_t(0))};
  }
  if (j.contains("crc32")) {
    rec.bytes = in.unsigned_at_most("bytes", std::numeric_limits<uint64_t>::max());
    rec.crc32 = uint32_t(in.unsigned_at_most("crc32", std::numeric_limits<uint32_t>::max()));
  }
  if (j.contains("original")) {
    const json& o = j["original"];
    rec.original_file = o.at("file").get<std::string>();
    rec.original.bytes = o.at("bytes").get<uint64_t>();
    rec.original.crc32 = o.at("crc32").get<uint32_t>();
  }
  std::error_code missing;  // A symlink loop or an unreadable entry is a missing frame too.
  if (!fs::exists(dir / rec.file, missing) || missing) {
    std::cerr << "warning: " << (dir / rec.file).string()
              << ": journaled frame is missing on disk; it will be captured again\n";
    return std::nullopt;
  }
  return rec;
}

}  // namespace

Session Session::create(const fs::path& dir, const Stage& stage, const SessionInfo& info) {
  if (fs::exists(dir / kManifest)) {
    if (const auto pid = SessionWriterLock::capturing(dir)) {
      throw InputError(dir.string() + ": a capture (process " + std::to_string(*pid) +
                       ") is writing this session: wait for it to end, or stop it and resume it " +
                       "with --resume " + dir.string());
    }
    throw InputError(dir.string() + ": already holds a session; resume it with --resume " +
                     dir.string() + " or choose another directory");
  }
  // What it makes is removed when it fails (a full disk): a session without its manifest is none.
  RunOutputs made(dir);
  std::error_code ec;
  if (!fs::exists(dir / "frames", ec)) made.add(dir / "frames");
  made.add(dir / kManifest);
  made.add(dir / kJournal);
  fs::create_directories(dir / "frames", ec);
  if (ec) throw StorageError(dir.string() + ": cannot create session directory: " + ec.message());
  // Detect a directory that takes no file (read-only, full) before any LED is switched on, with
  // the system's reason.
  const fs::path probe = dir / ".write-test";
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  const bool written = fd >= 0 && ::write(fd, "ok", 2) == 2 && ::fsync(fd) == 0;
  const int error = errno;
  if (fd >= 0) ::close(fd);
  fs::remove(probe, ec);
  if (!written) {
    throw StorageError(dir.string() +
                       ": cannot write in the session directory: " + std::strerror(error));
  }

  Session s;
  s.dir_ = dir;
  s.stage_ = stage;
  s.info_ = info;
  s.write_manifest("capturing");
  // Truncate any stale journal (no manifest means no session).
  std::ofstream journal(dir / kJournal, std::ios::trunc);
  if (!journal) throw StorageError((dir / kJournal).string() + ": cannot create the journal");
  made.keep();
  return s;
}

SessionWriterLock::SessionWriterLock(const fs::path& session_dir)
    : lock_(session_dir / "capture.lock",
            session_dir.string() + ": another capture is writing this session", ", then resume",
            /*remove_file=*/false) {}

std::optional<pid_t> SessionWriterLock::capturing(const fs::path& session_dir) {
  return WriterLock::holder(session_dir / "capture.lock");
}

Session Session::open(const fs::path& dir) {
  const fs::path manifest_path = dir / kManifest;
  if (!fs::exists(manifest_path)) {
    throw InputError(dir.string() + ": not a lightstage session (no " + kManifest + ")");
  }
  const std::string source = manifest_path.string();
  const json doc = JsonReader::parse(read_text(manifest_path), source);
  const JsonReader r(doc, source);
  if (!r.has("format") || r["format"].string() != kFormat) {
    r.fail(std::string("a manifest with \"format\": \"") + kFormat + "\"");
  }
  Session s;
  s.dir_ = dir;
  s.stage_ = parse_stage(r["stage"].value().dump(), source + " (stage)");
  s.info_.backend = r["backend"].string();
  s.info_.scene_file = r.has("scene_file") ? r["scene_file"].string() : "";
  if (r.has("camera_settings") && r["camera_settings"].value().is_object()) {
    for (const auto& [name, value] : r["camera_settings"].value().items()) {
      s.info_.camera_settings.emplace_back(name, r["camera_settings"][name].string());
    }
  }
  const JsonReader seed = r["seed"];
  if (!seed.value().is_number_unsigned()) seed.fail("a non-negative integer");
  s.info_.seed = seed.value().get<uint64_t>();

  sweep_temporary_frames(dir);

  // Replay the journal. A torn last line is ignored; its frame is captured again.
  const fs::path journal_path = dir / kJournal;
  std::istringstream journal(read_journal(journal_path));
  std::string line;
  int line_no = 0;
  while (std::getline(journal, line)) {
    ++line_no;
    if (line.empty()) continue;
    std::optional<json> parsed = parse_journal_line(line, journal_path, line_no);
    if (!parsed) continue;
    json& j = *parsed;  // Not const: operator[] of a missing key gives null, then a type error.
    // Valid JSON of the wrong shape, or naming a step, LED or exposure the plan has not, is a
    // damaged journal: say where, never abort.
    const JournalLine in{j, journal_path.string() + ":" + std::to_string(line_no), s.stage_};
    // Dark frames are repeats 0 .. dark_frames - 1; the reference LED's shots 1 .. shots.
    const int max_repeat =
        std::max(s.stage_.plan.dark_frames - 1,
                 s.stage_.plan.reference_shots(int(s.stage_.capture_order().size())));
    // The frame a line names: {t, led, e, r}, each within the plan.
    const auto frame_key = [&] {
      return FrameKey{in.step("t"), in.int_in("led", -1, int(s.stage_.leds.size()) - 1),
                      in.int_in("e", 0, int(s.stage_.camera.bracket.size()) - 1),
                      in.int_in("r", 0, max_repeat)};
    };
    try {
      if (j.contains("led_signal")) {
        s.led_signals_[{in.step("t"), in.led("led_signal")}] = j["fraction"].get<double>();
        continue;
      }
      if (j.contains("overrun")) {
        s.overruns_[in.step("overrun")] = {in.step("overrun"), j["capture_s"].get<double>(),
                                           j["interval_s"].get<double>()};
        continue;
      }
      if (j.contains("frame_problem")) {
        s.frame_problems_.push_back(
            {frame_key(), j["attempt"].get<int>(), j["frame_problem"].get<std::string>()});
        continue;
      }
      if (j.contains("dead_led")) {
        s.dead_leds_[in.led("dead_led")] = j.value("reason", "");
        continue;
      }
      if (const std::optional<FrameRecord> rec = read_frame_record(j, in, frame_key(), dir)) {
        s.frames_[rec->key] = *rec;
      }
    } catch (const json::exception& e) {
      throw InputError(
          journal_path.string() + ":" + std::to_string(line_no) +
          ": expected a frame {t, led, e, r, file, exposure_s, gain, scene_time_s, "
          "at, bytes, crc32}, an led_signal, an overrun, a frame_problem or a dead_led: " +
          e.what());
    }
  }
  return s;
}

std::vector<PlannedFrame> Session::missing_frames() const {
  std::vector<PlannedFrame> missing;
  for (const auto& f : plan_frames(stage_)) {
    if (!frames_.count(f.key)) missing.push_back(f);
  }
  return missing;
}

void Session::append_journal(const std::string& lines) const {
  const fs::path path = dir_ / kJournal;
  const int fd = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CREAT, 0644);
  if (fd < 0) {
    throw StorageError(path.string() +
                       ": cannot open journal for appending: " + std::strerror(errno));
  }
  const off_t end_before = ::lseek(fd, 0, SEEK_END);
  const ssize_t n = ::write(fd, lines.data(), lines.size());
  const int write_errno = errno;
  const bool ok = n == ssize_t(lines.size()) && ::fsync(fd) == 0;
  // A partial append (disk full) must not leave half a line for the next append to run into.
  if (!ok && end_before >= 0) {
    [[maybe_unused]] const int cut = ::ftruncate(fd, end_before);  // Best effort.
  }
  ::close(fd);
  if (!ok) {
    throw StorageError(path.string() +
                       ": cannot append to journal: " + std::strerror(n < 0 ? write_errno : errno));
  }
}

FrameRecord Session::write_frame_file(const PlannedFrame& planned,
                                      const CapturedFrame& frame) const {
  FrameRecord rec;
  rec.key = planned.key;
  rec.file = "frames/" + planned.key.name(stage_) + ".png";
  rec.exposure_s = frame.exposure_s;
  rec.gain = frame.gain;
  rec.scene_time_s = planned.request.scene_time_s;
  rec.captured_at = utc_now_iso8601();
  rec.timing = frame.timing;
  RawFrame raw = frame.raw;
  raw.bit_depth = stage_.camera.bit_depth;
  // Durable (fsync'ed and renamed) before it is journaled.
  const StoredFile stored = write_raw_frame(dir_ / rec.file, raw);
  rec.bytes = stored.bytes;
  rec.crc32 = stored.crc32;
  if (!frame.original_file.empty()) {
    rec.original_file = "originals/" + planned.key.name(stage_) +
                        fs::path(frame.original_name).extension().string();
    std::error_code ignored;  // A folder that cannot be made fails the write below, naming it.
    fs::create_directories(dir_ / "originals", ignored);
    write_file_atomic(dir_ / rec.original_file, frame.original_file.data(),
                      frame.original_file.size());
    rec.original = {frame.original_file.size(),
                    crc32_of(frame.original_file.data(), frame.original_file.size())};
  }
  return rec;
}

void Session::journal_frames(const std::vector<FrameRecord>& records) {
  std::string lines;
  for (const FrameRecord& rec : records) {
    json line{{"t", rec.key.time_step},
              {"led", rec.key.led_index},
              {"e", rec.key.exposure_index},
              {"r", rec.key.repeat},
              {"file", rec.file},
              {"exposure_s", rec.exposure_s},
              {"gain", rec.gain},
              {"scene_time_s", rec.scene_time_s},
              {"at", rec.captured_at},
              {"bytes", rec.bytes},
              {"crc32", rec.crc32},
              {"timing",
               {{"led_on_ns", rec.timing.led_on_ns},
                {"requested_ns", rec.timing.requested_ns},
                {"delivered_ns", rec.timing.delivered_ns},
                {"led_off_ns", rec.timing.led_off_ns},
                {"sensor_ns", rec.timing.sensor_ns}}}};
    if (!rec.original_file.empty()) {
      line["original"] = {{"file", rec.original_file},
                          {"bytes", rec.original.bytes},
                          {"crc32", rec.original.crc32}};
    }
    lines += line.dump() + "\n";
  }
  if (lines.empty()) return;
  append_journal(lines);
  for (const FrameRecord& rec : records) frames_[rec.key] = rec;
}

void Session::record_frame(const PlannedFrame& planned, const CapturedFrame& frame) {
  journal_frames({write_frame_file(planned, frame)});
}

RawFrame Session::load_frame(const FrameKey& key) const {
  const auto it = frames_.find(key);
  if (it == frames_.end()) {
    throw InputError(dir_.string() + ": frame " + key.name(stage_) + " was not captured");
  }
  return read_raw_frame(dir_ / it->second.file, stage_.camera.bit_depth);
}

void Session::mark_dead_led(int led_index, const std::string& reason) {
  if (dead_leds_.count(led_index)) return;
  append_journal(json{{"dead_led", led_index}, {"reason", reason}}.dump() + "\n");
  dead_leds_[led_index] = reason;
}

void Session::record_led_signal(int time_step, int led_index, double fraction) {
  append_journal(json{{"led_signal", led_index}, {"t", time_step}, {"fraction", fraction}}.dump() +
                 "\n");
  led_signals_[{time_step, led_index}] = fraction;
}

void Session::record_time_step_overrun(const TimeStepOverrun& overrun) {
  append_journal(json{{"overrun", overrun.time_step},
                      {"capture_s", overrun.capture_s},
                      {"interval_s", overrun.interval_s}}
                     .dump() +
                 "\n");
  overruns_[overrun.time_step] = overrun;
}

void Session::record_frame_problem(const FrameProblem& problem) {
  const FrameKey& k = problem.key;
  append_journal(json{{"frame_problem", problem.problem},
                      {"t", k.time_step},
                      {"led", k.led_index},
                      {"e", k.exposure_index},
                      {"r", k.repeat},
                      {"attempt", problem.attempt}}
                     .dump() +
                 "\n");
  frame_problems_.push_back(problem);
}

void Session::write_manifest(const std::string& status) const {
  json overruns = json::array();
  for (const auto& [step, o] : overruns_) {
    overruns.push_back({{"time_step", step},
                        {"scene_time_s", stage_.plan.step_time_s(step)},
                        {"capture_s", o.capture_s},
                        {"interval_s", o.interval_s}});
  }
  json dead = json::array();
  for (const auto& [index, reason] : dead_leds_) {
    dead.push_back({{"led_index", index}, {"led_id", stage_.leds[index].id}, {"reason", reason}});
  }
  json problems = json::array();
  for (const FrameProblem& p : frame_problems_) {
    problems.push_back(
        {{"frame", p.key.name(stage_)}, {"attempt", p.attempt}, {"problem", p.problem}});
  }
  json camera_settings = json::object();
  for (const auto& [name, value] : info_.camera_settings) camera_settings[name] = value;
  const size_t planned = plan_frames(stage_).size();
  const json doc = {{"format", kFormat},
                    {"status", status},
                    {"updated_at", utc_now_iso8601()},
                    {"backend", info_.backend},
                    {"scene_file", info_.scene_file},
                    {"seed", info_.seed},
                    {"camera_settings", camera_settings},
                    {"frames_planned", planned},
                    {"frames_captured", frames_.size()},
                    {"journal", kJournal},
                    {"dead_leds", dead},
                    {"time_step_overruns", overruns},
                    {"frame_problems", problems},
                    {"stage", json::parse(stage_to_json(stage_))}};
  write_file_atomic(dir_ / kManifest, doc.dump(2) + "\n");
}

namespace {

// What is wrong with a file saved as `stored`, or "" when it is as saved.
std::string stored_file_problem(const fs::path& path, const StoredFile& stored,
                                uint64_t& bytes_read) {
  std::error_code ec;
  const uint64_t size = fs::file_size(path, ec);
  if (ec) return "cannot read its size: " + ec.message();
  if (size != stored.bytes) {
    return std::to_string(size) + " bytes, the journal says " + std::to_string(stored.bytes);
  }
  std::ifstream in(path, std::ios::binary);
  std::vector<char> bytes(size);
  if (!in.read(bytes.data(), std::streamsize(size))) return "cannot read it";
  bytes_read += size;
  if (crc32_of(bytes.data(), bytes.size()) != stored.crc32) {
    return "its bytes changed since it was saved (CRC-32 differs from the journal's)";
  }
  return {};
}

// What is wrong with a journaled frame's file, or "" when it is as saved.
std::string frame_file_problem(const fs::path& path, const FrameRecord& rec, const Stage& stage,
                               uint64_t& bytes_read) {
  if (rec.bytes == 0) {  // Journaled without a checksum: it must decode at the camera's size.
    try {
      const RawFrame f = read_raw_frame(path, stage.camera.bit_depth);
      bytes_read += f.pixels.size() * sizeof(uint16_t);
      if (f.width != stage.camera.width || f.height != stage.camera.height ||
          f.channels != stage.camera.channels) {
        return std::to_string(f.width) + "x" + std::to_string(f.height) + "x" +
               std::to_string(f.channels) + " pixels, the camera's are " +
               std::to_string(stage.camera.width) + "x" + std::to_string(stage.camera.height) +
               "x" + std::to_string(stage.camera.channels);
      }
      return {};
    } catch (const InputError& e) {
      return e.what();
    }
  }
  return stored_file_problem(path, {rec.bytes, rec.crc32}, bytes_read);
}

}  // namespace

FrameCheck Session::verify_frames() {
  FrameCheck check;
  for (auto it = frames_.begin(); it != frames_.end();) {
    fs::path path = dir_ / it->second.file;
    std::string problem = frame_file_problem(path, it->second, stage_, check.bytes_read);
    if (problem.empty() && !it->second.original_file.empty()) {
      path = dir_ / it->second.original_file;
      problem = stored_file_problem(path, it->second.original, check.bytes_read);
    }
    if (problem.empty()) {
      ++check.verified;
      ++it;
    } else {
      check.damaged.push_back(path.string() + ": " + problem);
      it = frames_.erase(it);
    }
  }
  return check;
}

}  // namespace ls
