// Reflectance fields (capture/field.h): an EXR built from a description (fuzz_support.h) — its
// channels, layout and values, and the lightstage:lights, :noise, :view and :scene_time_s
// attributes — read whole (read_field, as fit and compress do) and in bands (FieldStream, as
// relight and the banded jobs do: a row at a time and as raw planar rows), then each pixel's
// directions to the lights.
#include "capture/field.h"
#include "capture/field_file.h"
#include "fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path file = ls::fuzz::work_dir() / "field.exr";
  if (!ls::fuzz::write_described_exr(ls::fuzz::as_text(data, size), file)) return -1;
  ls::fuzz::expect_only_input_errors([&] {
    const ls::capture::ReflectanceField field = ls::capture::read_field(file);
    ls::capture::FieldStream stream(file);
    ls::capture::ReflectanceField band;
    const int rows = stream.row_alignment();
    for (int y0 = 0; y0 < stream.height(); y0 += rows) {
      stream.read_rows(y0, std::min(stream.height(), y0 + rows), band);
    }
    stream.read_rows_planar(0, stream.height(), [](const ls::capture::PlanarRows&) {});
    (void)ls::capture::valid_lights(field);
    // Each pixel's own light directions (near LEDs seen from where the view puts the pixel), as
    // the fits gather them.
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        const ls::capture::PixelLightDirs dirs(field, x, y);
        for (int l = 0; l < field.num_lights(); ++l) (void)dirs(l);
      }
    }
  });
  return 0;
}
