// Time edit files (`lightstage relight --temporal T --edits FILE`, relight/time/temporal_render.h):
// parsed for 4 x 3 maps, applied to the fixture temporal maps (every process), and the edited
// maps evaluated at a time between the steps and one beyond them. The edit file's folder holds
// mask.png (4 x 3, the left half white) for "mask" selections.
#include <filesystem>

#include "fuzz/fuzz_fixtures.h"
#include "fuzz/fuzz_support.h"
#include "relight/time/temporal_render.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path& dir = ls::fuzz::edits_dir();
  static const ls::relight::TemporalMaps fixture = ls::fuzz::small_temporal_maps();
  ls::fuzz::expect_only_input_errors([&] {
    const ls::relight::TemporalEdits edits =
        ls::relight::parse_temporal_edits(ls::fuzz::as_text(data, size), "time.json", dir,
                                          ls::fuzz::kFixtureWidth, ls::fuzz::kFixtureHeight);
    ls::relight::TemporalMaps maps = fixture;
    (void)ls::relight::apply_temporal_edits(edits, maps);
    for (const double time_s : {45.0, 600.0}) (void)ls::relight::models_at_time(maps, time_s);
  });
  return 0;
}
