#include "evaluation/exposure_bench.h"

#include <algorithm>
#include <cmath>
#include <fstream>

#include "capture/build_field.h"
#include "capture/exposure_choice.h"
#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "sim/sim_stage.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

namespace {

constexpr uint64_t kSeed = 4;

// Captures `stage` into `dir`, builds it, and measures each LED that lights the view (2% of the
// brightest LED's rms) against truth, leaving out pixels that clip even at the shortest step
// (a highlight's lower bound in any plan).
ExposurePlanOutcome capture_and_measure(const fs::path& dir, const Stage& stage,
                                        const sim::Scene& scene, double camera_fps) {
  sim::SimStage sim(stage, scene, kSeed);
  Session session = Session::create(dir, stage, {});
  SequencerOptions instant;
  instant.sleep = [](double) {};
  const CaptureSummary captured = run_capture(session, sim.lights(), sim.camera(), instant);
  if (captured.status != CaptureSummary::Status::kComplete) {
    throw InputError(dir.string() + ": capture failed: " + captured.message);
  }
  ExposurePlanOutcome out;
  double shortest_s = stage.camera.bracket[0].exposure_s;
  for (const ExposureStep& step : stage.camera.bracket) {
    shortest_s = std::min(shortest_s, step.exposure_s);
  }
  for (const PlannedFrame& f : plan_frames(stage)) {
    if (f.key.is_dark()) continue;
    ++out.led_frames;
    out.exposure_s += f.request.exposure_s;
    out.capture_s += std::max(f.request.exposure_s, 1.0 / camera_fps);
  }
  const capture::ReflectanceField field = capture::build_field(session, {});
  std::vector<std::pair<double, double>> errors;  // (truth rms, relative RMSE) per LED.
  const std::vector<int> order = stage.capture_order();
  for (int l = 0; l < field.num_lights(); ++l) {
    const Led& led = stage.leds[size_t(order[l])];
    const Image truth = sim::render_one_light(sim.scene(), sim.hits(), led.dir_in_stage);
    const double to_full_scale = led.intensity * shortest_s / stage.camera.radiometric_scale;
    double d2 = 0, t2 = 0;
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        const float peak = std::max({truth.at(x, y, 0), truth.at(x, y, 1), truth.at(x, y, 2)});
        if (peak * to_full_scale > 0.9) continue;
        for (int c = 0; c < 3; ++c) {
          const double d = double(field.at(x, y, l, c)) - truth.at(x, y, c);
          d2 += d * d;
          t2 += double(truth.at(x, y, c)) * truth.at(x, y, c);
        }
      }
    }
    if (t2 > 0) {
      errors.push_back(
          {std::sqrt(t2 / (3.0 * field.width() * field.height())), std::sqrt(d2 / t2)});
    }
  }
  double brightest = 0;
  for (const auto& [rms, e] : errors) brightest = std::max(brightest, rms);
  std::vector<double> relevant;
  for (const auto& [rms, e] : errors) {
    if (rms >= 0.02 * brightest) relevant.push_back(e);
  }
  if (relevant.empty()) throw InputError(dir.string() + ": no LED lights the view");
  std::sort(relevant.begin(), relevant.end());
  out.median_error = relevant[relevant.size() / 2];
  out.p90_error = relevant[relevant.size() * 9 / 10];
  return out;
}

}  // namespace

ExposureBenchRow compare_exposure_plans(const std::string& scene_name, const sim::Scene& scene,
                                        const Stage& stage, const fs::path& dir,
                                        double camera_fps) {
  ExposureBenchRow row;
  row.scene = scene_name;
  row.whole = capture_and_measure(dir / "whole", stage, scene, camera_fps);
  Stage chosen = stage;
  chosen.plan.led_exposures =
      capture::choose_led_exposures(Session::open(dir / "whole")).led_exposures;
  row.chosen = capture_and_measure(dir / "chosen", chosen, scene, camera_fps);
  return row;
}

void write_exposure_chart(const fs::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  std::string at;  // Older files lack the read-out's frame rate.
  if (table.has("camera_fps") && !table.rows.empty()) {
    at = " at " + table.rows[0][table.column("camera_fps")] + " fps read-out";
  }
  Chart chart{.csv = csv,
              .x = "capture_s",
              .y = "median_error",
              .series = series_by("scene", table.distinct("scene")),
              .title = "Exposures chosen per LED against the whole bracket (labels: plan)",
              .x_label = "capture time per time step" + at + ", s",
              .y_label = "median LED error vs truth (relative)"};
  for (ChartSeries& s : chart.series) s.labels.column = "plan";
  write_chart(fs::path(csv).replace_filename("exposures_error_vs_time.png"), chart);
}

ExposureBenchSummary run_exposure_bench(const ExposureBenchOptions& options,
                                        const ProgressFn& progress) {
  throw_if_invalid(options.resolution < 16 || !(options.camera_fps > 0)
                       ? "bench exposures: expected --resolution >= 16 and --camera-fps > 0"
                       : "");
  fs::create_directories(options.out);
  Stage stage = default_stage();
  stage.camera.width = stage.camera.height = options.resolution;
  const std::vector<std::pair<std::string, sim::Scene>> scenes = {
      {"demo", sim::default_scene()}, {"hdr", sim::load_scene(options.hdr_scene)}};
  ExposureBenchSummary summary;
  const fs::path work = options.out / "exposures_sessions";
  for (size_t k = 0; k < scenes.size(); ++k) {
    report(progress, "exposures", long(k), long(scenes.size()), scenes[k].first);
    fs::remove_all(work / scenes[k].first);
    summary.rows.push_back(compare_exposure_plans(scenes[k].first, scenes[k].second, stage,
                                                  work / scenes[k].first, options.camera_fps));
  }
  report(progress, "exposures", long(scenes.size()), long(scenes.size()));
  fs::remove_all(work);
  summary.csv = options.out / "exposures.csv";
  std::ofstream csv(summary.csv);
  if (!csv) throw InputError(summary.csv.string() + ": cannot write");
  csv << "scene,plan,led_frames,exposure_s,capture_s,median_error,p90_error,camera_fps\n";
  for (const ExposureBenchRow& row : summary.rows) {
    for (const auto& [plan, o] : {std::pair{"whole bracket", row.whole}, {"chosen", row.chosen}}) {
      csv << row.scene << ',' << plan << ',' << o.led_frames << ',' << o.exposure_s << ','
          << o.capture_s << ',' << o.median_error << ',' << o.p90_error << ',' << options.camera_fps
          << '\n';
    }
  }
  csv.close();
  write_exposure_chart(summary.csv);
  return summary;
}

}  // namespace ls::evaluation
