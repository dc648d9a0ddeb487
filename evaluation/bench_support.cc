#include "evaluation/bench_support.h"

#include "capture/build_field.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "lightstage/session.h"
#include "sim/sim_stage.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

capture::ReflectanceField capture_sim_field(const Stage& stage, const sim::Scene& scene,
                                            const fs::path& session_dir, const std::string& phase,
                                            const ProgressFn& progress) {
  fs::remove_all(session_dir);
  capture::ReflectanceField field;
  {
    Session session = Session::create(session_dir, stage, {"sim", "", 1});
    sim::SimStage sim_stage(stage, scene, 1);
    const long total = long(plan_frames(stage).size());
    SequencerOptions options;
    options.sleep = [](double) {};
    options.on_progress = [&](const CaptureProgress& p) {
      if (p.done < total) report(progress, phase, p.done, total);
    };
    run_capture(session, sim_stage.lights(), sim_stage.camera(), options);
    report(progress, phase, total, total);
    field = capture::build_field(session, {});
  }
  fs::remove_all(session_dir);
  return field;
}

std::vector<relight::EnvironmentMap> load_maps(const std::vector<fs::path>& paths) {
  std::vector<relight::EnvironmentMap> maps;
  maps.reserve(paths.size());
  for (const fs::path& path : paths) maps.push_back(relight::EnvironmentMap::load(path));
  return maps;
}

void throw_if_invalid(const std::string& error) {
  if (!error.empty()) throw InputError(error);
}

}  // namespace ls::evaluation
