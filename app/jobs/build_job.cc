#include "app/jobs/build_job.h"

#include <cstdio>
#include <nlohmann/json.hpp>

#include "app/jobs/ranks.h"
#include "capture/field.h"
#include "lightstage/errors.h"
#include "lightstage/session.h"

namespace ls::jobs {

namespace fs = std::filesystem;

std::string BuildJobOptions::validate() const {
  if (session_dir.empty()) return "give the session directory";
  if (out.empty()) return "--out: give the field file (or, with --all-time-steps, a directory)";
  if (time_step < 0) return "--time-step: expected a step >= 0";
  if (all_time_steps && time_step != 0) return "--all-time-steps: drop --time-step";
  try {
    capture::parse_storage_choice("--storage", storage);
  } catch (const InputError& e) {
    return e.what();
  }
  return {};
}

std::string BuildJobOptions::to_json() const {
  nlohmann::json j;
  j["session"] = session_dir.string();
  j["time_step"] = time_step;
  j["all_time_steps"] = all_time_steps;
  j["storage"] = storage;
  j["correct_drift"] = correct_drift;
  return j.dump();
}

namespace {

BuiltField build_step(const Session& session, const BuildJobOptions& options, int time_step,
                      const fs::path& out, const ProgressFn& progress) {
  const Stage& stage = session.stage();
  if (time_step < 0 || time_step >= stage.plan.time_steps) {
    throw InputError(options.session_dir.string() + ": --time-step " + std::to_string(time_step) +
                     " is outside the session's 0.." + std::to_string(stage.plan.time_steps - 1));
  }
  capture::BuildOptions build;
  build.time_step = time_step;
  build.memory = options.memory;
  build.correct_drift = options.correct_drift;
  build.storage = capture::parse_storage_choice("--storage", options.storage);
  build.progress = progress;
  const Ranks& ranks = Ranks::world();
  build.split = ranks.split();
  BuiltField result;
  result.band_rows = capture::build_field_file(
      session, build, out, {{kOptionsAttribute, options.to_json()}}, &result.build);
  result.ranks = ranks.size();
  if (!ranks.root()) return result;  // Rank 0 wrote the field.
  result.file = out;
  result.time_step = time_step;
  result.scene_time_s = stage.plan.step_time_s(time_step);
  result.width = stage.camera.width;
  result.height = stage.camera.height;
  result.lights = int(stage.leds.size());
  result.mebibytes =
      capture::ReflectanceField::bytes_for(result.width, result.height, result.lights) / 1048576.0;
  result.file_mebibytes = double(fs::file_size(out)) / 1048576.0;
  for (int i : result.build.lights_missing) result.missing_led_ids.push_back(stage.leds[i].id);
  return result;
}

}  // namespace

BuildJobSummary build(const BuildJobOptions& options, const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("build: " + problem);
  }
  if (const std::optional<pid_t> capture = SessionWriterLock::capturing(options.session_dir)) {
    throw InputError(options.session_dir.string() + ": a capture (process " +
                     std::to_string(*capture) +
                     ") is writing this session: build it once the capture has ended");
  }
  const Session session = Session::open(options.session_dir);
  BuildJobSummary summary;
  summary.reference_z_m = session.stage().calibration.reference_z_m;
  if (!options.all_time_steps) {
    summary.fields.push_back(
        build_step(session, options, options.time_step, options.out, progress));
    return summary;
  }
  // One field per time step: DIR/field_t000.exr, ... (each stores its scene time, capture/field.h).
  std::error_code ec;
  const bool existed = fs::exists(options.out, ec);
  fs::create_directories(options.out, ec);
  if (ec || !fs::is_directory(options.out)) {
    throw InputError(options.out.string() + ": --out: expected a directory for --all-time-steps (" +
                     (ec ? ec.message() : std::string("not a directory")) + ")");
  }
  try {
    for (int t = 0; t < session.stage().plan.time_steps; ++t) {
      char name[32];
      std::snprintf(name, sizeof name, "field_t%03d.exr", t);
      summary.fields.push_back(build_step(session, options, t, options.out / name, progress));
    }
  } catch (...) {
    // The folder this run made goes with it when nothing in it (a field, a step's .partial/ kept
    // for resuming) is worth keeping.
    if (!existed && fs::is_empty(options.out, ec)) fs::remove(options.out, ec);
    throw;
  }
  return summary;
}

}  // namespace ls::jobs
