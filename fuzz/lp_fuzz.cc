// RTI light-position files (`lightstage import X.lp`, capture/olat_import.h): any text as the .lp
// file of a folder holding three 4 x 3 PNGs (a.png, b.png, sub/c.png), imported into a field. Lines
// that name those images (as written, with Windows backslashes, or by file name alone) import.
#include <filesystem>

#include "capture/olat_import.h"
#include "fuzz/fuzz_fixtures.h"
#include "fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::filesystem::path folder = [] {
    std::filesystem::path path = ls::fuzz::work_dir() / "lp";
    std::filesystem::create_directories(path / "sub");
    for (const char* image : {"a.png", "b.png", "sub/c.png"}) {
      ls::fuzz::write_half_white_png(path / image);
    }
    return path;
  }();
  const std::filesystem::path lp = ls::fuzz::write_file("lp/set.lp", ls::fuzz::as_text(data, size));
  ls::fuzz::expect_only_input_errors([&] {
    ls::capture::OlatImportSummary summary;
    (void)ls::capture::import_rti_lp(lp, {}, &summary);
  });
  return 0;
}
