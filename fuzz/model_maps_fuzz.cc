// Model maps (`lightstage fit --out MAPS.exr`, relight/fit/fit.h): an EXR built from a description
// (fuzz_support.h) — its channels and values, the lightstage:fit_noise and :materials attributes —
// read as relight --models and the viewer read it, then rendered under one light (what every
// reader of maps does next).
#include "fuzz/fuzz_support.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path file = ls::fuzz::work_dir() / "maps.exr";
  if (!ls::fuzz::write_described_exr(ls::fuzz::as_text(data, size), file)) return -1;
  ls::fuzz::expect_only_input_errors([&] {
    const ls::relight::ModelMaps maps = ls::relight::read_model_maps(file);
    const auto light = ls::relight::LightingForModels::directional(
        Eigen::Vector3d(0.2, 0.5, 0.8).normalized(), Eigen::Vector3d(1, 1, 1));
    (void)ls::relight::render_models(maps, light);
  });
  return 0;
}
