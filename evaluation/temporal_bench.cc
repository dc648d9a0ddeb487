#include "evaluation/temporal_bench.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "evaluation/temporal_held_out.h"
#include "lightstage/errors.h"
#include "relight/fit/normals.h"
#include "relight/time/temporal_fit.h"
#include "relight/time/temporal_render.h"
#include "sim/noisy_field.h"
#include "sim/sim_stage.h"
#include "sim/time_varying.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

std::string TemporalBenchOptions::validate() const {
  if (steps.empty()) return "bench temporal: steps: expected at least one number of time steps";
  for (const int n : steps) {
    if (n < 1 || n > 64) return "bench temporal: steps: expected 1..64, got " + std::to_string(n);
  }
  if (leds < 8 || leds > 2000) {
    return "bench temporal: leds: expected 8..2000, got " + std::to_string(leds);
  }
  if (width < 4 || width > 1024 || height < 4 || height > 1024) {
    return "bench temporal: width and height: expected 4..1024 pixels, got " +
           std::to_string(width) + " x " + std::to_string(height);
  }
  if (!(duration_s > 0)) return "bench temporal: duration: expected a positive number of seconds";
  for (const int n : captured) {
    if (n < 2 || n > lapse_steps) {
      return "bench temporal: captured: expected 2.." + std::to_string(lapse_steps) + ", got " +
             std::to_string(n);
    }
  }
  if (lapse_steps < 2 || lapse_steps > 64) {
    return "bench temporal: lapse steps: expected 2..64, got " + std::to_string(lapse_steps);
  }
  return {};
}

namespace {

// The scene, its stage and its surface hits at time 0 (the ground truth).
struct World {
  Stage stage;
  sim::Scene scene;
  std::vector<sim::SurfaceHit> hits;
};

World make_world(const TemporalBenchOptions& options) {
  World w;
  w.stage = stage_with_directions(fibonacci_dome_directions(options.leds, -11.5));
  w.stage.camera.width = options.width;
  w.stage.camera.height = options.height;
  w.scene = sim::time_varying_scene();
  for (sim::SceneMaterial& m : w.scene.materials) {
    // A wet surface dries to its own base colour.
    if (m.process && m.process->kind == sim::ProcessKind::kWetDrying) m.process->dry = m.base;
  }
  w.hits = sim::trace_camera(w.scene, w.stage.camera);
  return w;
}

// Relative RMS error of the models rendered at uncaptured times against the ideal one-light truth,
// over lit surface pixels with a model.
double render_error(const World& w, const relight::TemporalMaps& maps, double duration_s) {
  double err2 = 0, ref2 = 0;
  const Eigen::Vector3d light = Eigen::Vector3d(0.25, 0.3, 0.92).normalized();
  for (const double t : {0.25 * duration_s, 0.55 * duration_s, 0.85 * duration_s}) {
    const Image truth = sim::render_one_light(w.scene, sim::at_time(w.scene, w.hits, t), light);
    const Image model = relight::render_temporal(
        maps, t, relight::LightingForModels::directional(light, Eigen::Vector3d(1, 1, 1)));
    for (const sim::SurfaceHit& h : w.hits) {
      if (!h.hit || maps.model(h.pixel_x, h.pixel_y) == relight::TemporalModel::kNone) continue;
      if (!sim::visible(w.scene, h.position + 1e-3 * h.normal, light)) continue;
      for (int c = 0; c < 3; ++c) {
        const double d = model.at(h.pixel_x, h.pixel_y, c) - truth.at(h.pixel_x, h.pixel_y, c);
        err2 += d * d;
        ref2 += double(truth.at(h.pixel_x, h.pixel_y, c)) * truth.at(h.pixel_x, h.pixel_y, c);
      }
    }
  }
  return ref2 > 0 ? std::sqrt(err2 / ref2) : 0;
}

// The recovered processes against the true ones: rate error, recall and static pixels kept.
void score_processes(const World& w, const relight::TemporalMaps& maps, TemporalBenchRow& row) {
  std::vector<double> rate_errors;
  int varying = 0, varying_found = 0, still = 0, still_constant = 0;
  for (const sim::SurfaceHit& h : w.hits) {
    if (!h.hit || h.material_index < 0) continue;
    const sim::ProcessTruth truth =
        sim::truth_at(w.scene.materials[h.material_index], h.st.x(), h.st.y());
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
}

TemporalBenchRow run_steps(const World& w, int n, double duration_s) {
  std::vector<capture::ReflectanceField> fields;
  for (int i = 0; i < n; ++i) {
    sim::SimFieldOptions at;
    at.scene_time_s = n == 1 ? 0 : duration_s * i / (n - 1);
    fields.push_back(sim::render_noisy_field(w.stage, w.scene,
                                             relight::NoiseModel{}.as_field_noise(), 100 + i, at));
  }
  const relight::TemporalMaps maps = relight::fit_temporal(fields, {});
  TemporalBenchRow row;
  row.steps = n;
  const double pixels = maps.summary.pixels;
  row.step_fit_us_per_pixel_step = 1e6 * maps.summary.seconds_steps / (pixels * n);
  row.temporal_fit_us_per_pixel = 1e6 * maps.summary.seconds_temporal / pixels;
  row.render_error = render_error(w, maps, duration_s);
  score_processes(w, maps, row);
  return row;
}

void write_temporal_csv(const fs::path& path, const std::vector<TemporalBenchRow>& rows,
                        double duration_s) {
  std::ofstream csv(path);
  if (!csv) throw InputError(path.string() + ": cannot write");
  csv << "steps,step_fit_us_per_pixel_step,temporal_fit_us_per_pixel,render_rel_rms_error,"
         "median_rate_rel_error,varying_recall,static_constant,duration_s\n";
  for (const TemporalBenchRow& r : rows) {
    csv << r.steps << ',' << r.step_fit_us_per_pixel_step << ',' << r.temporal_fit_us_per_pixel
        << ',' << r.render_error << ',';
    // Too few steps for any process: no rate was recovered, so there is no rate error to show.
    if (r.varying_recall > 0) csv << r.median_rate_error;
    csv << ',' << r.varying_recall << ',' << r.static_constant << ',' << duration_s << '\n';
  }
}

}  // namespace

void write_temporal_charts(const fs::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  std::string over;  // Older files lack the duration.
  if (table.has("duration_s") && !table.rows.empty()) {
    over = " over " + table.rows[0][table.column("duration_s")] + " s";
  }
  write_chart(
      fs::path(csv).replace_filename("temporal_error_vs_steps.png"),
      {.csv = csv,
       .x = "steps",
       .series = {{.title = "relit error",
                   .y = "render_rel_rms_error",
                   .labels = {.column = "temporal_fit_us_per_pixel", .format = "%.0f us/px"}},
                  {.title = "median rate error", .y = "median_rate_rel_error"}},
       .title = "Temporal fit: error against ground truth vs time steps (labels: temporal fit "
                "time per pixel)",
       .x_label = "time steps" + over,
       .y_label = "relative error"});
  write_chart(
      fs::path(csv).replace_filename("temporal_time_vs_steps.png"),
      {.csv = csv,
       .x = "steps",
       .series = {{.title = "per-step BRDF fits, us / pixel / step",
                   .y = "step_fit_us_per_pixel_step"},
                  {.title = "temporal model fits, us / pixel", .y = "temporal_fit_us_per_pixel"}},
       .title = "Temporal fit: time per pixel vs time steps",
       .x_label = "time steps",
       .y_label = "microseconds"});
}

void write_temporal_held_out_chart(const fs::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  std::string of;  // Older files lack the time lapse's steps.
  if (table.has("lapse_steps") && !table.rows.empty()) {
    of = " of " + table.rows[0][table.column("lapse_steps")] + " over 1200 s";
  }
  const std::string stem = csv.stem().string();
  const bool dark = table.has("exposure") && !table.rows.empty() &&
                    std::stod(table.rows[0][table.column("exposure")]) < 1;
  const bool dim = table.has("dim_samples") && !table.rows.empty() &&
                   table.rows[0][table.column("dim_samples")] == "1";
  write_chart(
      fs::path(csv).replace_filename(stem + "_vs_steps.png"),
      {.csv = csv,
       .x = "captured_steps",
       .series = {{.title = "temporal fit", .y = "temporal_fit"},
                  {.title = "models by BIC alone", .y = "by_bic_alone"},
                  {.title = "processes only", .y = "processes_only"},
                  {.title = "per-step fits interpolated", .y = "step_fits_interpolated"},
                  {.title = "photos: linear interpolation", .y = "linear_interpolation"},
                  {.title = "photos: nearest captured step", .y = "nearest_step"}},
       .title = dim ? "Held-out steps of the rise-and-fall scene 5x darker, its dim samples "
                      "readmitted: relative error"
                    : std::string("Held-out time steps of the rise-and-fall scene") +
                          (dark ? ", 5x darker capture" : "") +
                          ": relative error vs steps captured",
       .x_label = "steps captured" + of,
       .y_label = "relative RMS error"});
}

namespace {

void write_held_out_csv(const fs::path& path, const std::vector<HeldOutBenchRow>& rows,
                        int lapse_steps) {
  std::ofstream csv(path);
  if (!csv) throw InputError(path.string() + ": cannot write");
  csv << "exposure,captured_steps,temporal_fit,by_bic_alone,processes_only,step_fits_interpolated,"
         "linear_interpolation,nearest_step,fit_at_captured,step_fits_at_captured,photos_at_"
         "captured,"
         "curve_families,"
         "lapse_steps,dim_samples\n";
  for (const HeldOutBenchRow& r : rows) {
    csv << r.exposure << ',' << r.captured << ',' << r.fit << ',' << r.by_bic_alone << ','
        << r.processes_only << ',' << r.step_fits_interpolated << ',' << r.linear << ','
        << r.nearest << ',' << r.fit_at_captured << ',' << r.step_fits_at_captured << ','
        << r.photos_at_captured << ',' << r.curve_families << ',' << lapse_steps << ','
        << int(r.dim_samples) << '\n';
  }
  csv.close();
  write_temporal_held_out_chart(path);
}

// The held-out part (see the header): per exposure (and, for the dark one, with its dim samples
// readmitted too) one row per number of captured steps, its CSV and chart, and the time-edit
// figure from the capture of every other step.
std::vector<HeldOutBenchRow> run_held_out(const TemporalBenchOptions& options,
                                          const ProgressFn& progress) {
  std::vector<HeldOutBenchRow> all;
  const long runs = 3 * long(options.captured.size());
  for (const double exposure : {1.0, 0.2}) {
    const bool dark = exposure < 1;
    const TimeLapse lapse =
        rise_and_fall_time_lapse(151, 32, 24, options.lapse_steps, 1200.0, 40, exposure);
    for (const bool dim_samples : {false, true}) {
      if (dim_samples && !dark) continue;
      relight::TemporalFitOptions fit;
      fit.brdf.readmit_dim_samples = dim_samples;
      std::vector<HeldOutBenchRow> rows;
      for (const int n : options.captured) {
        const HeldOutScores s =
            score_held_out(lapse, evenly_spaced_steps(options.lapse_steps, n), fit);
        rows.push_back({exposure, dim_samples, n, total(s.fit).relative(),
                        total(s.by_bic_alone).relative(), total(s.processes_only).relative(),
                        total(s.step_fits_interpolated).relative(), total(s.linear).relative(),
                        total(s.nearest).relative(), total(s.fit_at_captured).relative(),
                        total(s.step_fits_at_captured).relative(),
                        total(s.photos_at_captured).relative(), int(s.maps.curves.size())});
        report(progress, "held-out steps", long(all.size() + rows.size()), runs,
               std::to_string(n) + " captured at exposure " + std::to_string(exposure) +
                   (dim_samples ? ", dim samples readmitted" : ""));
      }
      const std::string name = std::string("temporal_held_out") + (dark ? "_dark" : "") +
                               (dim_samples ? "_dim" : "") + ".csv";
      write_held_out_csv(options.out / name, rows, options.lapse_steps);
      all.insert(all.end(), rows.begin(), rows.end());
    }
    if (!dark) {
      std::vector<capture::ReflectanceField> every_other;
      for (const int i : evenly_spaced_steps(options.lapse_steps, (options.lapse_steps + 1) / 2)) {
        every_other.push_back(lapse.noisy[size_t(i)]);
      }
      write_time_edit_figure(options.out / "temporal_edits.png", lapse,
                             relight::fit_temporal(every_other, {}));
    }
  }
  return all;
}

}  // namespace

TemporalBenchSummary run_temporal_bench(const TemporalBenchOptions& options,
                                        const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  const World w = make_world(options);
  TemporalBenchSummary summary;
  const long total = long(options.steps.size());
  for (const int n : options.steps) {
    summary.rows.push_back(run_steps(w, n, options.duration_s));
    report(progress, "temporal bench", long(summary.rows.size()), total,
           std::to_string(n) + " steps");
  }
  summary.csv = options.out / "temporal.csv";
  write_temporal_csv(summary.csv, summary.rows, options.duration_s);
  write_temporal_charts(summary.csv);
  if (!options.captured.empty()) summary.held_out = run_held_out(options, progress);
  return summary;
}

}  // namespace ls::evaluation
