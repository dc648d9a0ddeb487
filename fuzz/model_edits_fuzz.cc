// Edit files (`lightstage relight --models MAPS --edits FILE`, relight/fit/model_edit.h): parsed
// for 4 x 3 maps and applied to the fixture maps (every model, two basis materials). The edit
// file's folder holds mask.png (4 x 3, the left half white) for "mask" selections.
#include <filesystem>

#include "fuzz/fuzz_fixtures.h"
#include "fuzz/fuzz_support.h"
#include "relight/fit/model_edit.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path& dir = ls::fuzz::edits_dir();
  static const ls::relight::ModelMaps fixture = ls::fuzz::small_model_maps();
  ls::fuzz::expect_only_input_errors([&] {
    const ls::relight::ModelEdits edits =
        ls::relight::parse_model_edits(ls::fuzz::as_text(data, size), "edits.json", dir,
                                       ls::fuzz::kFixtureWidth, ls::fuzz::kFixtureHeight);
    ls::relight::ModelMaps maps = fixture;
    (void)ls::relight::apply_model_edits(edits, maps);
  });
  return 0;
}
