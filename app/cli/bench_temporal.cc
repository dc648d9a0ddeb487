// lightstage bench temporal: time-varying BRDF fits (relight/time/temporal_fit.h) on the
// simulator's time-varying scene as the number of time steps grows: fit time per pixel (per-step
// BRDF fits and temporal model fits) and the error against ground truth (rendering at uncaptured
// times, and the recovered rates). Writes temporal.csv and two charts.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <random>

#include "app/cli/chart.h"
#include "lightstage/progress.h"
#include "lightstage/stage.h"
#include "relight/time/temporal_fit.h"
#include "relight/time/temporal_render.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
#include "sim/time_varying.h"

namespace ls::cli {

namespace fs = std::filesystem;

namespace {

struct TemporalBenchArgs {
  fs::path out = "bench-out/temporal";
  std::vector<int> steps{3, 5, 8, 12, 20};
  int leds = 40;
  int width = 32;
  int height = 24;
  double duration_s = 600;
};

// Ideal one-light field at time t plus noise from the fit's noise model.
capture::ReflectanceField field_at(const Stage& stage, const sim::Scene& scene,
                                   const std::vector<sim::SurfaceHit>& hits, double time_s,
                                   uint64_t seed) {
  const std::vector<sim::SurfaceHit> timed = sim::at_time(scene, hits, time_s);
  std::vector<capture::FieldLight> lights;
  for (const Led& led : stage.leds) lights.push_back({led.id, led.dir_in_stage, true});
  capture::ReflectanceField field(stage.camera.width, stage.camera.height, lights);
  field.scene_time_s = time_s;
  field.source = "sim";
  const relight::NoiseModel noise;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss;
  for (int l = 0; l < int(stage.leds.size()); ++l) {
    const Image image = sim::render_one_light(scene, timed, stage.leds[l].dir_in_stage);
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        for (int c = 0; c < 3; ++c) {
          const double v = image.at(x, y, c);
          field.at(x, y, l, c) = float(v + std::sqrt(noise.variance(v)) * gauss(rng));
        }
      }
    }
  }
  return field;
}

struct Row {
  int steps = 0;
  double step_fit_us_per_pixel_step = 0;
  double temporal_fit_us_per_pixel = 0;
  double render_error = 0;       // Relative RMS at uncaptured times vs the ideal one-light truth.
  double median_rate_error = 0;  // |rate / true - 1| over varying pixels given a process.
  double varying_recall = 0;     // Varying pixels given a non-constant model.
  double static_constant = 0;    // Static pixels given the constant model.
};

void run_temporal_bench(const TemporalBenchArgs& args) {
  fs::create_directories(args.out);
  Stage stage = stage_with_directions(fibonacci_dome_directions(args.leds, -11.5));
  stage.camera.width = args.width;
  stage.camera.height = args.height;
  sim::Scene scene = sim::time_varying_scene();
  for (sim::SceneMaterial& m : scene.materials) {
    // A wet surface dries to its own base colour.
    if (m.process && m.process->kind == sim::ProcessKind::kWetDrying) m.process->dry = m.base;
  }
  const std::vector<sim::SurfaceHit> hits = sim::trace_camera(scene, stage.camera);
  const std::vector<double> test_times = {0.25 * args.duration_s, 0.55 * args.duration_s,
                                          0.85 * args.duration_s};
  std::vector<Row> rows;
  ProgressReporter progress("temporal bench", long(args.steps.size()));
  for (const int n : args.steps) {
    std::vector<capture::ReflectanceField> fields;
    for (int i = 0; i < n; ++i) {
      const double t = n == 1 ? 0 : args.duration_s * i / (n - 1);
      fields.push_back(field_at(stage, scene, hits, t, 100 + i));
    }
    const relight::TemporalMaps maps = relight::fit_temporal(fields, {});
    Row row;
    row.steps = n;
    const double pixels = maps.summary.pixels;
    row.step_fit_us_per_pixel_step = 1e6 * maps.summary.seconds_steps / (pixels * n);
    row.temporal_fit_us_per_pixel = 1e6 * maps.summary.seconds_temporal / pixels;
    double err2 = 0, ref2 = 0;
    const Eigen::Vector3d light = Eigen::Vector3d(0.25, 0.3, 0.92).normalized();
    for (const double t : test_times) {
      const Image truth = sim::render_one_light(scene, sim::at_time(scene, hits, t), light);
      const Image model = relight::render_temporal(
          maps, t, relight::LightingForModels::directional(light, Eigen::Vector3d(1, 1, 1)));
      for (const sim::SurfaceHit& h : hits) {
        if (!h.hit || maps.model(h.pixel_x, h.pixel_y) == relight::TemporalModel::kNone) continue;
        if (!sim::visible(scene, h.position + 1e-3 * h.normal, light)) continue;
        for (int c = 0; c < 3; ++c) {
          const double d = model.at(h.pixel_x, h.pixel_y, c) - truth.at(h.pixel_x, h.pixel_y, c);
          err2 += d * d;
          ref2 += double(truth.at(h.pixel_x, h.pixel_y, c)) * truth.at(h.pixel_x, h.pixel_y, c);
        }
      }
    }
    row.render_error = ref2 > 0 ? std::sqrt(err2 / ref2) : 0;
    std::vector<double> rate_errors;
    int varying = 0, varying_found = 0, still = 0, still_constant = 0;
    for (const sim::SurfaceHit& h : hits) {
      if (!h.hit || h.material_index < 0) continue;
      const sim::ProcessTruth truth =
          sim::truth_at(scene.materials[h.material_index], h.st.x(), h.st.y());
      const relight::TemporalModel m = maps.model(h.pixel_x, h.pixel_y);
      if (m == relight::TemporalModel::kNone) continue;
      if (!truth.varying) {
        ++still;
        still_constant += m == relight::TemporalModel::kConstant;
        continue;
      }
      ++varying;
      if (m == relight::TemporalModel::kConstant) continue;
      ++varying_found;
      rate_errors.push_back(
          std::abs(maps.at(h.pixel_x, h.pixel_y, relight::kTRate) / truth.rate_per_s - 1));
    }
    if (!rate_errors.empty()) {
      std::nth_element(rate_errors.begin(), rate_errors.begin() + rate_errors.size() / 2,
                       rate_errors.end());
      row.median_rate_error = rate_errors[rate_errors.size() / 2];
    }
    row.varying_recall = varying > 0 ? double(varying_found) / varying : 0;
    row.static_constant = still > 0 ? double(still_constant) / still : 0;
    rows.push_back(row);
    progress.update(long(rows.size()), std::to_string(n) + " steps");
  }
  progress.done();

  std::ofstream csv(args.out / "temporal.csv");
  csv << "steps,step_fit_us_per_pixel_step,temporal_fit_us_per_pixel,render_rel_rms_error,"
         "median_rate_rel_error,varying_recall,static_constant\n";
  std::printf("%6s %22s %22s %12s %12s %10s %10s\n", "steps", "step fit us/px/step",
              "temporal fit us/px", "render err", "rate err", "recall", "static ok");
  ChartSeries error{"relit error", {}, {}, {}, true};
  ChartSeries rate{"median rate error", {}, {}, {}, true};
  ChartSeries step_time{"per-step BRDF fits, us / pixel / step", {}, {}, {}, true};
  ChartSeries temporal_time{"temporal model fits, us / pixel", {}, {}, {}, true};
  for (const Row& r : rows) {
    // Too few steps for any process: no rate was recovered, so there is no rate error to show.
    const bool has_rates = r.varying_recall > 0;
    csv << r.steps << ',' << r.step_fit_us_per_pixel_step << ',' << r.temporal_fit_us_per_pixel
        << ',' << r.render_error << ',';
    if (has_rates) csv << r.median_rate_error;
    csv << ',' << r.varying_recall << ',' << r.static_constant << '\n';
    std::printf("%6d %22.1f %22.1f %12.4f %12.4f %10.3f %10.3f\n", r.steps,
                r.step_fit_us_per_pixel_step, r.temporal_fit_us_per_pixel, r.render_error,
                r.median_rate_error, r.varying_recall, r.static_constant);
    error.x.push_back(r.steps);
    error.y.push_back(r.render_error);
    if (has_rates) {
      rate.x.push_back(r.steps);
      rate.y.push_back(r.median_rate_error);
    }
    step_time.x.push_back(r.steps);
    step_time.y.push_back(r.step_fit_us_per_pixel_step);
    temporal_time.x.push_back(r.steps);
    temporal_time.y.push_back(r.temporal_fit_us_per_pixel);
    char label[48];
    std::snprintf(label, sizeof label, "%.0f us/px", r.temporal_fit_us_per_pixel);
    error.point_labels.push_back(label);
  }
  write_chart(args.out / "temporal_error_vs_steps.png",
              {"Temporal fit: error against ground truth vs time steps (labels: temporal fit "
               "time per pixel)",
               "time steps over " + std::to_string(int(args.duration_s)) + " s", "error", false},
              {error, rate});
  write_chart(args.out / "temporal_time_vs_steps.png",
              {"Temporal fit: time per pixel vs time steps", "time steps", "microseconds", false},
              {step_time, temporal_time});
  std::fprintf(stderr, "wrote %s, temporal_error_vs_steps.png, temporal_time_vs_steps.png\n",
               (args.out / "temporal.csv").c_str());
}

}  // namespace

void add_bench_temporal_command(CLI::App& bench) {
  auto args = std::make_shared<TemporalBenchArgs>();
  auto* cmd = bench.add_subcommand(
      "temporal",
      "Time-varying BRDF fits on the simulator's time-varying scene as the number of time steps "
      "grows: fit time per pixel and error against ground truth (render at uncaptured times, "
      "recovered rates). Writes temporal.csv and two charts.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_option("--steps", args->steps, "Numbers of time steps.")
      ->delimiter(',')
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  cmd->add_option("--leds", args->leds, "LEDs on the Fibonacci dome.")
      ->check(CLI::Range(8, 2000))
      ->capture_default_str();
  cmd->add_option("--width", args->width, "Image width.")->check(CLI::Range(4, 1024));
  cmd->add_option("--height", args->height, "Image height.")->check(CLI::Range(4, 1024));
  cmd->add_option("--duration", args->duration_s, "Scene seconds covered by the steps.")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->callback([args] { run_temporal_bench(*args); });
}

}  // namespace ls::cli
