// Scene files (sim/scene.h): parse_scene on any text. A scene it accepts must also trace and
// shade: a few pixels of a small camera, at the start and later in scene time (time-varying
// materials), under one light.
#include "fuzz/fuzz_support.h"
#include "lightstage/stage.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ls::fuzz::expect_only_input_errors([&] {
    const ls::sim::Scene scene = ls::sim::parse_scene(
        ls::fuzz::as_text(data, size), (ls::fuzz::work_dir() / "scene.json").string());
    ls::CameraSpec camera;
    camera.width = 6;
    camera.height = 4;
    for (const double time_s : {0.0, 300.0}) {
      const auto hits = ls::sim::trace_camera(scene, camera, time_s);
      (void)ls::sim::render_one_light(scene, hits, Eigen::Vector3d(0.3, 0.8, 0.5).normalized());
    }
  });
  return 0;
}
