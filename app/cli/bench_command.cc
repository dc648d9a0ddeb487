// lightstage bench: speed and accuracy measurements that write CSV and chart images.
//  leds:       relighting accuracy and speed as the number of LEDs grows. For each dome size: a
//              simulated capture of the demo scene, its field, relighting under each shipped map
//              (median time over repeats), and the error against ground truth rendered directly
//              from the scene. Writes leds.csv and two charts (PSNR against relight time; error
//              against LEDs).
//  fit-sweeps: failure sweeps of normals and fits (evaluation/fit_sweeps.h): fit_sweeps.csv and
//              one chart per axis (normal error against the axis, flagged fraction as labels).
//  fit:        per-pixel model fits against field relighting: fit throughput and the error of
//              relighting from each model (and the BIC choice) against ground truth, with the
//              field-relighting points on the same chart (fit.csv, fit_error_vs_time.png).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <optional>

#include "app/cli/chart.h"
#include "app/cli/commands.h"
#include "capture/build_field.h"
#include "evaluation/fit_sweeps.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/image_metrics.h"
#include "lightstage/progress.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "relight/fit/normals.h"
#include "relight/lighting/envmap.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
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
      const double relight_ms = median_ms(
          args.repeats, [&] { relight::relight_into(field, weights.irradiance_rgb, relit); });
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

struct FitSweepArgs {
  fs::path out = "bench-out";
  bool quick = false;
  int height = 16;
  int leds = 80;
};

void run_fit_sweeps_bench(const FitSweepArgs& args) {
  fs::create_directories(args.out);
  sim::FitSweepOptions options;
  options.quick = args.quick;
  options.height = args.height;
  options.width = 3 * args.height;
  options.leds = args.leds;
  int total = 0;
  for (const sim::SweepAxis axis : options.axes) total += int(options.values(axis).size());
  ProgressReporter progress("fit sweeps", total);
  options.on_progress = [&](int done, int) { progress.update(done); };
  const std::vector<sim::SweepPoint> points = sim::run_fit_sweeps(options);
  progress.done();
  sim::write_fit_sweeps_csv(args.out / "fit_sweeps.csv", points);

  auto show = [](const std::optional<double>& v, double scale = 1.0) {
    char text[32];
    if (!v) return std::string("-");
    std::snprintf(text, sizeof text, "%.3g", *v * scale);
    return std::string(text);
  };
  std::printf("%-22s %7s %8s %8s %8s %8s %7s %7s %7s %6s %5s %5s %8s\n", "axis", "value", "LS deg",
              "rob deg", "fit deg", "fit p95", "flag%", "model%", "albedo%", "gross", "impl",
              "inval", "fit px/s");
  for (const sim::SweepPoint& p : points) {
    std::printf("%-22s %7g %8s %8s %8s %8s %7.1f %7s %7s %6d %5d %5d %8.0f\n", to_string(p.axis),
                p.value, show(p.least_squares.mean_deg).c_str(), show(p.robust.mean_deg).c_str(),
                show(p.fit.mean_deg).c_str(), show(p.fit.p95_deg).c_str(),
                100 * p.fit.flagged_fraction, show(p.model_accuracy, 100).c_str(),
                show(p.albedo_rel, 100).c_str(), p.unflagged_gross_errors, p.unflagged_implausible,
                p.invalid_outputs, p.fit_pixels_per_second);
  }
  for (const sim::SweepAxis axis : options.axes) {
    std::vector<ChartSeries> series(4);
    series[0].name = "LS normals, mean";
    series[1].name = "robust normals, mean";
    series[2].name = "fit normals, mean";
    series[3].name = "fit normals, p95";
    for (const sim::SweepPoint& p : points) {
      if (p.axis != axis) continue;
      const std::optional<double>* y[4] = {&p.least_squares.mean_deg, &p.robust.mean_deg,
                                           &p.fit.mean_deg, &p.fit.p95_deg};
      for (int k = 0; k < 4; ++k) {
        // Everything flagged: no error to plot (the chart skips non-finite points).
        series[k].x.push_back(p.value);
        series[k].y.push_back(y[k]->value_or(std::numeric_limits<double>::quiet_NaN()));
      }
      char label[48];
      std::snprintf(label, sizeof label, "%.0f%% flagged", 100 * p.fit.flagged_fraction);
      series[2].point_labels.push_back(label);
    }
    write_chart(
        args.out / ("fit_sweeps_" + std::string(to_string(axis)) + ".png"),
        {"Normal error vs " + std::string(sim::axis_label(axis)) + " (labels: fit, % flagged)",
         sim::axis_label(axis), "angular error of the normal, deg",
         axis == sim::SweepAxis::kLedCount},
        series);
  }
  int invalid = 0;
  for (const sim::SweepPoint& p : points) invalid += p.invalid_outputs;
  std::fprintf(stderr, "wrote %s and fit_sweeps_<axis>.png; %d invalid outputs\n",
               (args.out / "fit_sweeps.csv").c_str(), invalid);
}

struct FitBenchArgs {
  fs::path out = "bench-out";
  int leds = 150;
  int resolution = 64;
  int repeats = 5;
};

// One fit configuration: which candidate models the BIC choice may pick from. Lambert is always a
// candidate (FitOptions has no switch for it), so "Oren-Nayar" is Lambert-or-Oren-Nayar etc.
struct FitConfig {
  std::string name;
  bool oren_nayar, torrance_sparrow, phong;
};

void run_fit_bench(const FitBenchArgs& args) {
  fs::create_directories(args.out);
  const sim::Scene scene = sim::default_scene();
  Stage stage = stage_with_directions(fibonacci_dome_directions(args.leds, -11.5));
  stage.camera.width = stage.camera.height = args.resolution;
  const fs::path dir = args.out / "session_fit";
  fs::remove_all(dir);
  capture::ReflectanceField field;
  {
    Session session = Session::create(dir, stage, {"sim", "", 1});
    sim::SimStage sim_stage(stage, scene, 1);
    ProgressReporter progress("capture", long(plan_frames(stage).size()));
    SequencerOptions options;
    options.sleep = [](double) {};
    options.on_progress = [&](const CaptureProgress& p) { progress.update(p.done); };
    run_capture(session, sim_stage.lights(), sim_stage.camera(), options);
    progress.done();
    field = capture::build_field(session, {});
  }
  fs::remove_all(dir);  // Frames are only a means here.

  relight::FitOptions base;
  base.use_noise_of(field);
  std::fprintf(stderr, "noise: %s: variance = %.3g + %.3g * v\n", base.noise_source.c_str(),
               base.normals.noise.a, base.normals.noise.b);
  const double pixels = double(field.width()) * field.height();
  const auto t0 = std::chrono::steady_clock::now();
  const relight::NormalMap normals = relight::estimate_normals(field, base.normals);
  const double normals_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const std::vector<FitConfig> configs{{"Lambert", false, false, false},
                                       {"Oren-Nayar", true, false, false},
                                       {"Lambert+TS", false, true, false},
                                       {"Lambert+Phong", false, false, true},
                                       {"BIC (L, ON, L+TS)", true, true, false}};
  std::vector<relight::ModelMaps> maps;
  std::vector<double> fit_s;
  for (const FitConfig& config : configs) {
    relight::FitOptions options = base;
    options.fit_oren_nayar = config.oren_nayar;
    options.fit_torrance_sparrow = config.torrance_sparrow;
    options.fit_phong = config.phong;
    ProgressReporter progress("fit " + config.name, field.height());
    options.progress = [&](long done, long) { progress.update(done); };
    const auto start = std::chrono::steady_clock::now();
    maps.push_back(relight::fit_models(field, normals, options));
    fit_s.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    progress.done();
  }

  std::vector<relight::EnvironmentMap> env_maps;
  for (const auto& path : shipped_environment_maps(false))
    env_maps.push_back(relight::EnvironmentMap::load(path));
  const auto dirs = stage.led_directions();
  const double coverage = relight::max_nearest_neighbour_angle(dirs);
  std::ofstream csv(args.out / "fit.csv");
  csv << "method,map,fit_s,normals_s,fit_pixels_per_s,render_ms,time_to_frame_s,relative_rmse,"
         "psnr_db,flagged_fraction\n";
  std::vector<ChartSeries> by_time(env_maps.size()), by_rate(env_maps.size());
  std::printf("%-18s %-14s %9s %11s %10s %9s %8s %8s\n", "method", "map", "fit s", "fit px/s",
              "render ms", "rel.RMSE", "PSNR", "flagged");
  for (size_t m = 0; m < env_maps.size(); ++m) {
    const std::string map_name = fs::path(env_maps[m].source()).stem().string();
    by_time[m].name = by_rate[m].name = map_name;
    by_time[m].connect = by_rate[m].connect = false;  // Methods, not a sequence.
    const relight::LightWeights weights =
        relight::integrate_environment(env_maps[m], dirs, 0.0, coverage);
    sim::GroundTruthOptions gt;
    gt.covered_by_leds = dirs;
    gt.coverage_radius_rad = coverage;
    const Image truth = sim::render_ground_truth(scene, stage.camera, env_maps[m], gt);
    Image field_relit;
    const double relight_ms = median_ms(
        args.repeats, [&] { relight::relight_into(field, weights.irradiance_rgb, field_relit); });
    const ImageError field_error = compare_images(field_relit, truth);
    csv << "field," << map_name << ",0,0,0," << relight_ms << ',' << relight_ms / 1e3 << ','
        << field_error.relative_rmse << ',' << field_error.psnr_db << ",0\n";
    std::printf("%-18s %-14s %9s %11s %10.3f %9.4f %8.2f %8s\n", "field", map_name.c_str(), "-",
                "-", relight_ms, field_error.relative_rmse, field_error.psnr_db, "-");
    by_time[m].x.push_back(relight_ms / 1e3);
    by_time[m].y.push_back(field_error.relative_rmse);
    by_time[m].point_labels.push_back("field");
    // Models lit by the same per-LED irradiances as the field: the difference is what the models
    // get wrong (no shadows, misfit), not how the map was sampled. Flagged pixels take the field's
    // value, as a viewer would show them.
    const relight::LightingForModels lighting =
        relight::LightingForModels::led_cells(dirs, weights);
    relight::ModelRenderOptions render_options;
    render_options.flagged_fallback = &field_relit;
    for (size_t k = 0; k < configs.size(); ++k) {
      Image relit;
      const double render_ms = median_ms(
          args.repeats, [&] { relit = relight::render_models(maps[k], lighting, render_options); });
      const ImageError error = compare_images(relit, truth);
      const double rate = fit_s[k] > 0 ? pixels / fit_s[k] : 0.0;
      const double flagged = double(maps[k].summary.flagged) / pixels;
      const double to_frame = normals_s + fit_s[k] + render_ms / 1e3;
      csv << configs[k].name << ',' << map_name << ',' << fit_s[k] << ',' << normals_s << ','
          << rate << ',' << render_ms << ',' << to_frame << ',' << error.relative_rmse << ','
          << error.psnr_db << ',' << flagged << '\n';
      std::printf("%-18s %-14s %9.2f %11.0f %10.3f %9.4f %8.2f %7.1f%%\n", configs[k].name.c_str(),
                  map_name.c_str(), fit_s[k], rate, render_ms, error.relative_rmse, error.psnr_db,
                  100 * flagged);
      by_time[m].x.push_back(to_frame);
      by_time[m].y.push_back(error.relative_rmse);
      by_time[m].point_labels.push_back(configs[k].name);
      by_rate[m].x.push_back(rate);
      by_rate[m].y.push_back(error.relative_rmse);
      by_rate[m].point_labels.push_back(configs[k].name);
    }
  }
  const std::string size = std::to_string(args.resolution) + "x" + std::to_string(args.resolution) +
                           " px, " + std::to_string(args.leds) + " LEDs";
  write_chart(
      args.out / "fit_error_vs_time.png",
      {"Relighting error vs time to a frame (" + size + ")",
       "s: field relight | normals + fit + model render", "relative RMSE vs ground truth", true},
      by_time);
  write_chart(args.out / "fit_error_vs_throughput.png",
              {"Model relighting error vs fit throughput (" + size + ")",
               "fit throughput, pixels/s (all cores)", "relative RMSE vs ground truth", true},
              by_rate);
  std::fprintf(stderr, "wrote %s, fit_error_vs_time.png, fit_error_vs_throughput.png\n",
               (args.out / "fit.csv").c_str());
}

}  // namespace

void add_bench_temporal_command(CLI::App& bench);  // bench_temporal.cc

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

  auto sweep_args = std::make_shared<FitSweepArgs>();
  auto* sweeps = bench->add_subcommand(
      "fit-sweeps",
      "Failure sweeps of photometric-stereo normals and per-pixel fits on simulated ground truth: "
      "noise, LED count (down to below the minimum), light-direction error, shadowed fraction, "
      "saturation, dead LEDs and grazing normals. Writes fit_sweeps.csv and one chart per axis.");
  sweeps->add_option("--out", sweep_args->out, "Output directory.")->capture_default_str();
  sweeps->add_flag("--quick", sweep_args->quick, "Three values per axis.");
  sweeps->add_option("--height", sweep_args->height, "Image height in pixels (width is 3x).")
      ->check(CLI::Range(4, 512))
      ->capture_default_str();
  sweeps->add_option("--leds", sweep_args->leds, "LEDs on every axis but the LED count.")
      ->check(CLI::Range(4, 2000))
      ->capture_default_str();
  sweeps->callback([sweep_args] { run_fit_sweeps_bench(*sweep_args); });

  auto fit_args = std::make_shared<FitBenchArgs>();
  auto* fit = bench->add_subcommand(
      "fit",
      "Per-pixel model fits against field relighting on the demo scene: fit throughput of each "
      "model (Lambert, Oren-Nayar, Lambert + Torrance-Sparrow, Lambert + Phong, and the BIC "
      "choice) and the error of relighting from it under every shipped map against ground "
      "truth, with the field's relighting on the same chart. Writes fit.csv and two charts.");
  fit->add_option("--out", fit_args->out, "Output directory.")->capture_default_str();
  fit->add_option("--leds", fit_args->leds, "LEDs on the Fibonacci dome.")
      ->check(CLI::Range(8, 2000))
      ->capture_default_str();
  fit->add_option("--resolution", fit_args->resolution, "Camera width and height.")
      ->check(CLI::Range(8, 1024))
      ->capture_default_str();
  fit->add_option("--repeats", fit_args->repeats, "Timed repeats of relighting (median).")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  fit->callback([fit_args] { run_fit_bench(*fit_args); });
  add_bench_temporal_command(*bench);
}

}  // namespace ls::cli
