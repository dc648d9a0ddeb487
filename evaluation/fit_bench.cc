#include "evaluation/fit_bench.h"

#include <algorithm>
#include <cmath>
#include <fstream>

#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "evaluation/model_metrics.h"
#include "lightstage/errors.h"
#include "lightstage/image_metrics.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "relight/fit/normals.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/ground_truth.h"
#include "sim/sim_stage.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

std::string FitBenchOptions::validate() const {
  if (leds < 8 || leds > 2000)
    return "bench fit: leds: expected 8..2000, got " + std::to_string(leds);
  if (resolution < 8 || resolution > 1024) {
    return "bench fit: resolution: expected 8..1024 pixels, got " + std::to_string(resolution);
  }
  if (repeats < 1 || repeats > 1000) {
    return "bench fit: repeats: expected 1..1000, got " + std::to_string(repeats);
  }
  if (maps.empty()) return "bench fit: maps: expected at least one environment map";
  return {};
}

namespace {

// One fit configuration: which candidate models the BIC choice may pick from, and the solver
// (relight::FitSolver: the profiled solver, the default, or LM on every candidate).
// Lambert is always a candidate (FitOptions has no switch for it), so "Oren-Nayar" is
// Lambert-or-Oren-Nayar etc.
struct FitConfig {
  std::string name;
  bool oren_nayar, torrance_sparrow, phong;
  relight::FitSolver solver;
  relight::FitMaterials materials = relight::FitMaterials::kPerPixel;
  bool fine_render = false;  // Also rendered under the map's finely sampled directions.
};

const std::vector<FitConfig>& fit_configs() {
  static const std::vector<FitConfig> configs = [] {
    const std::vector<FitConfig> models{{"Lambert", false, false, false, {}},
                                        {"Oren-Nayar", true, false, false, {}},
                                        {"Lambert+TS", false, true, false, {}},
                                        {"Lambert+Phong", false, false, true, {}},
                                        {"BIC (L / ON / L+TS)", true, true, false, {}}};
    std::vector<FitConfig> out;
    for (const relight::FitSolver solver :
         {relight::FitSolver::kProfiled, relight::FitSolver::kEveryCandidateByLm}) {
      for (FitConfig config : models) {
        config.solver = solver;
        config.name += solver == relight::FitSolver::kProfiled ? " [profiled]" : " [LM]";
        config.fine_render = config.oren_nayar && config.torrance_sparrow;
        out.push_back(config);
      }
    }
    out.push_back({"basis materials", true, true, false, relight::FitSolver::kProfiled,
                   relight::FitMaterials::kBasis, true});
    return out;
  }();
  return configs;
}

// The normals and every configuration's fit of one field, with their times.
struct Fits {
  double normals_s = 0;
  std::vector<relight::ModelMaps> maps;  // One per fit_configs() entry.
  std::vector<double> fit_s;
};

Fits fit_all(const capture::ReflectanceField& field, const relight::FitOptions& base,
             const ProgressFn& progress) {
  Fits fits;
  const auto t0 = std::chrono::steady_clock::now();
  const relight::NormalMap normals = relight::estimate_normals(field, base.normals);
  fits.normals_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (const FitConfig& config : fit_configs()) {
    relight::FitOptions options = base;
    options.fit_oren_nayar = config.oren_nayar;
    options.fit_torrance_sparrow = config.torrance_sparrow;
    options.fit_phong = config.phong;
    options.solver = config.solver;
    options.materials = config.materials;
    const std::string phase = "fit " + config.name;
    options.progress = [&](const std::string&, long done, long total, const std::string&) {
      if (done < total) report(progress, phase, done, total);
    };
    const auto start = std::chrono::steady_clock::now();
    fits.maps.push_back(relight::fit_models(field, normals, options));
    fits.fit_s.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    report(progress, phase, field.height(), field.height());
  }
  return fits;
}

// The field's row and every fit's under one map, against the scene's ground truth.
std::vector<FitBenchRow> rows_for_map(const capture::ReflectanceField& field, const Fits& fits,
                                      const Stage& stage, const sim::Scene& scene,
                                      const std::vector<sim::SurfaceHit>& hits,
                                      const physics::EnvironmentMap& map, int repeats) {
  const std::string map_name = fs::path(map.source()).stem().string();
  const auto dirs = stage.led_directions();
  const double coverage = max_nearest_neighbour_angle(dirs);
  const relight::LightWeights weights = relight::integrate_environment(map, dirs, 0.0, coverage);
  sim::GroundTruthOptions gt;
  gt.covered_by_leds = dirs;
  gt.coverage_radius_rad = coverage;
  const Image truth = sim::render_ground_truth(scene, stage.camera, map, gt);
  Image field_relit;
  const double relight_ms = median_ms(
      repeats, [&] { relight::relight_into(field, weights.irradiance_rgb, field_relit); });
  const ImageError field_error = compare_images(field_relit, truth);
  std::vector<FitBenchRow> rows;
  FitBenchRow row;
  row.method = "field";
  row.map = map_name;
  row.render_ms = relight_ms;
  row.time_to_frame_s = relight_ms / 1e3;
  row.relative_rmse = field_error.relative_rmse;
  row.psnr_db = field_error.psnr_db;
  rows.push_back(row);
  // Models lit by the same per-LED irradiances as the field: the difference is what the models
  // get wrong (no shadows, misfit), not how the map was sampled. Flagged pixels take the field's
  // value, as a viewer would show them.
  const relight::LightingForModels lighting = relight::LightingForModels::led_cells(dirs, weights);
  // The map sampled finely over what the dome covers (the truth's directions): a lobe lit by
  // one light per LED cell is sampled as coarsely as the dome; here only the models' own error
  // remains (no shadows, misfit).
  relight::EnvironmentSampling fine;
  fine.directions_width = 128;
  fine.covered_by_leds = dirs;
  fine.coverage_radius_rad = coverage;
  const relight::LightingForModels fine_lighting =
      relight::LightingForModels::environment(map, 0.0, fine);
  relight::ModelRenderOptions render_options;
  render_options.flagged_fallback = &field_relit;
  const double pixels = double(field.width()) * field.height();
  for (size_t k = 0; k < fit_configs().size(); ++k) {
    Image relit;
    row = {};
    row.method = fit_configs()[k].name;
    row.map = map_name;
    row.render_ms = median_ms(
        repeats, [&] { relit = relight::render_models(fits.maps[k], lighting, render_options); });
    const ImageError error = compare_images(relit, truth);
    row.fit_s = fits.fit_s[k];
    row.normals_s = fits.normals_s;
    row.fit_pixels_per_s = row.fit_s > 0 ? pixels / row.fit_s : 0.0;
    row.flagged_fraction = double(fits.maps[k].summary.flagged) / pixels;
    row.time_to_frame_s = fits.normals_s + row.fit_s + row.render_ms / 1e3;
    row.relative_rmse = error.relative_rmse;
    row.psnr_db = error.psnr_db;
    if (fit_configs()[k].fine_render) {
      row.fine_relative_rmse =
          compare_images(relight::render_models(fits.maps[k], fine_lighting, render_options), truth)
              .relative_rmse;
    }
    row.speckle = model_speckle(fits.maps[k]);
    row.wrong_on_lambertian =
        models_on(fits.maps[k], hits, relight::FitModel::kLambert).wrong_fraction();
    row.materials = int(fits.maps[k].materials.size());
    rows.push_back(row);
  }
  return rows;
}

void write_fit_csv(const fs::path& path, const FitBenchOptions& options,
                   const std::vector<FitBenchRow>& rows) {
  std::ofstream csv(path);
  if (!csv) throw InputError(path.string() + ": cannot write");
  csv << "method,map,fit_s,normals_s,fit_pixels_per_s,render_ms,time_to_frame_s,relative_rmse,"
         "psnr_db,flagged_fraction,speckle,wrong_on_lambertian,materials,fine_relative_rmse,"
         "resolution,leds\n";
  for (const FitBenchRow& r : rows) {
    csv << csv_field(r.method) << ',' << csv_field(r.map) << ',' << r.fit_s << ',' << r.normals_s
        << ',' << r.fit_pixels_per_s << ',' << r.render_ms << ',' << r.time_to_frame_s << ','
        << r.relative_rmse << ',' << r.psnr_db << ',' << r.flagged_fraction << ',' << r.speckle
        << ',' << r.wrong_on_lambertian << ',' << r.materials << ',' << r.fine_relative_rmse << ','
        << options.resolution << ',' << options.leds << '\n';
  }
}

// The method whose errors under the maps lie furthest apart (the largest smallest gap): the map
// names beside its points do not run into each other.
std::string spread_method(const CsvTable& table, const std::vector<std::string>& methods) {
  const std::vector<double> error = table.numbers("relative_rmse");
  const size_t method = table.column("method");
  std::string best;
  double best_gap = -1;
  for (const std::string& m : methods) {
    std::vector<double> ys;
    for (size_t r = 0; r < table.rows.size(); ++r) {
      if (table.rows[r][method] == m && std::isfinite(error[r])) ys.push_back(error[r]);
    }
    std::sort(ys.begin(), ys.end());
    double gap = INFINITY;
    for (size_t k = 1; k < ys.size(); ++k) gap = std::min(gap, ys[k] - ys[k - 1]);
    if (!ys.empty() && gap > best_gap) {
      best = m;
      best_gap = gap;
    }
  }
  return best;
}

}  // namespace

void write_fit_charts(const fs::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  std::string size;  // Older files lack the camera's size and the LEDs.
  if (table.has("resolution") && table.has("leds") && !table.rows.empty()) {
    const std::string& res = table.rows[0][table.column("resolution")];
    size = " (" + res + "x" + res + " px, " + table.rows[0][table.column("leds")] + " LEDs)";
  }
  // One series per method (methods, not a sequence: points alone); the maps named beside one
  // method's points.
  std::vector<std::string> methods = table.distinct("method");
  Chart chart{.csv = csv,
              .x = "time_to_frame_s",
              .y = "relative_rmse",
              .series = series_by("method", methods),
              .title = "Relighting error vs time to a frame" + size,
              .x_label = "seconds: field relight | normals + fit + model render",
              .y_label = "relative RMSE vs ground truth",
              .log_x = true,
              .lines = false};
  const auto label_maps = [&] {
    const std::string labelled = spread_method(table, methods);
    for (ChartSeries& s : chart.series) {
      if (s.title == labelled) s.labels.column = "map";
    }
  };
  label_maps();
  write_chart(fs::path(csv).replace_filename("fit_error_vs_time.png"), chart);
  std::erase(methods, "field");  // No fit, no throughput.
  chart.x = "fit_pixels_per_s";
  chart.series = series_by("method", methods);
  chart.title = "Model relighting error vs fit throughput" + size;
  chart.x_label = "fit throughput, pixels/s (all cores)";
  label_maps();
  write_chart(fs::path(csv).replace_filename("fit_error_vs_throughput.png"), chart);
}

FitBenchSummary run_fit_bench(const FitBenchOptions& options, const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  const sim::Scene scene = sim::default_scene();
  Stage stage = stage_with_directions(fibonacci_dome_directions(options.leds, -11.5));
  stage.camera.width = stage.camera.height = options.resolution;
  const capture::ReflectanceField field =
      capture_sim_field(stage, scene, options.out / "session_fit", "capture", progress);

  relight::FitOptions base;
  base.use_noise_of(field);
  FitBenchSummary summary;
  summary.noise_source = base.noise_source;
  summary.noise_read_variance = base.normals.noise.a;
  summary.noise_shot_variance_per_unit = base.normals.noise.b;
  const Fits fits = fit_all(field, base, progress);
  const std::vector<sim::SurfaceHit> hits = sim::trace_camera(scene, stage.camera);
  for (const physics::EnvironmentMap& map : load_maps(options.maps)) {
    for (FitBenchRow& row : rows_for_map(field, fits, stage, scene, hits, map, options.repeats)) {
      summary.rows.push_back(std::move(row));
    }
  }
  summary.csv = options.out / "fit.csv";
  write_fit_csv(summary.csv, options, summary.rows);
  write_fit_charts(summary.csv);
  return summary;
}

}  // namespace ls::evaluation
