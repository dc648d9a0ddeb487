// Temporal maps (`lightstage fit --time --out T.exr`, relight/time/temporal_fit.h): an EXR built
// from a description (fuzz_support.h) — its channels and values, the lightstage:temporal attribute
// — read as relight --temporal reads it, then evaluated at its first step, between steps and far
// beyond the last (what relight --temporal --time does next).
#include "fuzz/fuzz_support.h"
#include "relight/time/temporal_render.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path file = ls::fuzz::work_dir() / "temporal.exr";
  if (!ls::fuzz::write_described_exr(ls::fuzz::as_text(data, size), file)) return -1;
  ls::fuzz::expect_only_input_errors([&] {
    const ls::relight::TemporalMaps maps = ls::relight::read_temporal_maps(file);
    for (const double time_s :
         {maps.first_time_s(), 0.5 * (maps.first_time_s() + maps.last_time_s()),
          maps.last_time_s() + 1e4}) {
      (void)ls::relight::models_at_time(maps, time_s);
    }
  });
  return 0;
}
