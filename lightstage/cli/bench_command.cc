// lightstage bench leds: accuracy and speed of relighting as the number of LEDs grows.
// For each dome size: a simulated capture of the demo scene, its field, relighting under each
// shipped map (median time over repeats), and the error against ground truth rendered directly
// from the scene. Writes leds.csv and two charts (PSNR against relight time; error against LEDs).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "capture/build_field.h"
#include "lightstage/cli/chart.h"
#include "lightstage/cli/commands.h"
#include "lightstage/image_metrics.h"
#include "lightstage/progress.h"
#include "lightstage/sequencer.h"
#include "relight/envmap.h"
#include "relight/light_cells.h"
#include "relight/relight.h"
#include "sim/ground_truth.h"
#include "sim/sim_stage.h"

namespace ls::cli {

namespace fs = std::filesystem;

namespace {

struct BenchArgs {
  fs::path out = "bench-out";
  std::vector<int> counts{20, 40, 80, 150, 300};
  int resolution = 128;
  int repeats = 21;
};

template <class F>
double median_ms(int repeats, F&& f) {
  std::vector<double> ms;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

void run_led_bench(const BenchArgs& args) {
  fs::create_directories(args.out);
  const sim::Scene scene = sim::default_scene();
  std::vector<relight::EnvironmentMap> maps;
  for (const auto& path : shipped_environment_maps(false))
    maps.push_back(relight::EnvironmentMap::load(path));

  std::ofstream csv(args.out / "leds.csv");
  csv << "leds,map,relative_rmse,psnr_db,relight_ms,relight_gb_per_s,light_weights_ms,"
         "uncovered_fraction\n";
  std::vector<ChartSeries> speed(maps.size()), error(maps.size());
  for (size_t m = 0; m < maps.size(); ++m) {
    speed[m].name = error[m].name = fs::path(maps[m].source()).stem().string();
  }
  std::printf("%6s %-14s %10s %8s %11s %11s %10s\n", "LEDs", "map", "rel.RMSE", "PSNR",
              "relight ms", "weights ms", "uncovered");
  for (int count : args.counts) {
    Stage stage = stage_with_directions(fibonacci_dome_directions(count, -11.5));
    stage.camera.width = stage.camera.height = args.resolution;
    const fs::path dir = args.out / ("session_" + std::to_string(count));
    fs::remove_all(dir);
    Session session = Session::create(dir, stage, {"sim", "", 1});
    sim::SimStage sim_stage(stage, scene, 1);
    ProgressReporter progress("capture " + std::to_string(count), long(plan_frames(stage).size()));
    SequencerOptions options;
    options.sleep = [](double) {};
    options.on_progress = [&](const CaptureProgress& p) { progress.update(p.done); };
    run_capture(session, sim_stage.lights(), sim_stage.camera(), options);
    progress.done();
    const capture::ReflectanceField field = capture::build_field(session, {});
    fs::remove_all(dir);  // Frames are only a means here.

    const auto dirs = stage.led_directions();
    const double coverage = relight::max_nearest_neighbour_angle(dirs);
    for (size_t m = 0; m < maps.size(); ++m) {
      relight::LightWeights weights;
      const double weights_ms = median_ms(
          3, [&] { weights = relight::integrate_environment(maps[m], dirs, 0.0, coverage); });
      Image relit;
      const double relight_ms = median_ms(args.repeats, [&] {
        relight::relight_into(field, weights.irradiance_rgb.data(), relit);
      });
      sim::GroundTruthOptions gt;
      gt.covered_by_leds = dirs;
      gt.coverage_radius_rad = coverage;
      const Image truth = sim::render_ground_truth(scene, stage.camera, maps[m], gt);
      const ImageError err = compare_images(relit, truth);
      const double rel = err.relative_rmse, psnr = err.psnr_db;
      csv << count << ',' << speed[m].name << ',' << rel << ',' << psnr << ',' << relight_ms << ','
          << field.bytes() / (relight_ms * 1e6) << ',' << weights_ms << ','
          << weights.uncovered_fraction() << '\n';
      std::printf("%6d %-14s %10.4f %8.2f %11.3f %11.2f %9.2f%%\n", count, speed[m].name.c_str(),
                  rel, psnr, relight_ms, weights_ms, 100 * weights.uncovered_fraction());
      speed[m].x.push_back(relight_ms);
      speed[m].y.push_back(psnr);
      speed[m].point_labels.push_back(std::to_string(count));
      error[m].x.push_back(count);
      error[m].y.push_back(rel);
    }
  }
  const std::string res = std::to_string(args.resolution);
  write_chart(args.out / "leds_psnr_vs_time.png",
              {"Relighting from the field: PSNR vs time per frame (" + res + "x" + res +
                   " px, point labels = LEDs)",
               "relight time per frame, ms", "PSNR vs ground truth, dB", true},
              speed);
  write_chart(
      args.out / "leds_error_vs_count.png",
      {"Relighting error against ground truth vs number of LEDs", "LEDs", "relative RMSE", true},
      error);
  std::fprintf(stderr, "wrote %s, leds_psnr_vs_time.png, leds_error_vs_count.png\n",
               (args.out / "leds.csv").c_str());
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto* bench =
      app.add_subcommand("bench", "Measure speed and accuracy; writes CSV and chart images.");
  bench->require_subcommand(1);
  auto args = std::make_shared<BenchArgs>();
  auto* leds = bench->add_subcommand(
      "leds",
      "Relighting accuracy against ground truth, and time per frame, as the number of LEDs "
      "grows (Fibonacci domes of the given sizes, the demo scene, every shipped map).");
  leds->add_option("--out", args->out, "Output directory.")->capture_default_str();
  leds->add_option("--counts", args->counts, "Dome sizes.")->delimiter(',')->capture_default_str();
  leds->add_option("--resolution", args->resolution, "Camera width and height.")
      ->capture_default_str();
  leds->add_option("--repeats", args->repeats, "Timed repeats (median reported).")
      ->capture_default_str();
  leds->callback([args] { run_led_bench(*args); });
}

}  // namespace ls::cli
