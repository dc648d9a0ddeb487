#pragma once
// Builds a reflectance field the way a user does (simulated capture -> session -> build), in a
// temporary directory, for the end-to-end tests.
#include <filesystem>

#include "capture/build_field.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/session.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"

namespace ls::testing {

inline capture::ReflectanceField CaptureAndBuild(const std::filesystem::path& dir,
                                                 const Stage& stage, const sim::Scene& scene,
                                                 uint64_t seed = 1) {
  Session session = Session::create(dir, stage, {"sim", "", seed});
  sim::SimStage sim_stage(stage, scene, seed);
  SequencerOptions options;
  options.sleep = [](double) {};
  const CaptureSummary summary =
      run_capture(session, sim_stage.lights(), sim_stage.camera(), options);
  if (summary.status != CaptureSummary::Status::kComplete) {
    throw std::runtime_error("capture failed: " + summary.message);
  }
  return capture::build_field(session, {});
}

}  // namespace ls::testing
