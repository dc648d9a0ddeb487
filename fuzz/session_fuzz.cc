// Session folders (lightstage/session.h): the manifest and the frame journal, as
// `lightstage capture --resume` and `lightstage build` open them. Input: the manifest's text, a
// line "--", then the journal's. The folder holds every frame of the fixture stage
// (fuzz_fixtures.h), so journal lines naming them are frames. A session Session::open accepts must
// also do what a resume and a build do with it: list the missing frames, rewrite the manifest,
// build the field (where the plan and the camera are small enough to build in a moment).
#include <filesystem>

#include "capture/build_field.h"
#include "fuzz/fuzz_fixtures.h"
#include "fuzz/fuzz_support.h"
#include "lightstage/session.h"

namespace {

namespace fs = std::filesystem;

const fs::path& session_dir() {
  static const fs::path dir = [] {
    fs::path path = ls::fuzz::work_dir() / "session";
    ls::fuzz::write_small_frames(path, ls::fuzz::small_stage());
    return path;
  }();
  return dir;
}

// The plan's frames and the field's values, bounded so that one input takes milliseconds (a
// stage of 10^4 LEDs and 10^3 time steps is valid, and slow for the wrong reason).
bool small_enough(const ls::Stage& stage) {
  const double exposures = double(stage.camera.bracket.size());
  const double frames =
      (double(stage.leds.size()) + stage.plan.dark_frames) * exposures * stage.plan.time_steps;
  const double values = double(stage.camera.width) * stage.camera.height * 3 * stage.leds.size();
  return frames <= 2000 && values <= 1e5;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::vector<std::string> parts = ls::fuzz::split_parts(ls::fuzz::as_text(data, size));
  const fs::path& dir = session_dir();
  ls::fuzz::write_file("session/manifest.json", parts[0]);
  ls::fuzz::write_file("session/frames.jsonl", parts.size() > 1 ? parts[1] : "");
  ls::fuzz::expect_only_input_errors([&] {
    ls::Session session = ls::Session::open(dir);
    if (!small_enough(session.stage())) return;
    (void)session.missing_frames();
    session.write_manifest("interrupted");
    (void)ls::capture::build_field(session, {});
  });
  return 0;
}
