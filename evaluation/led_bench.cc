#include "evaluation/led_bench.h"

#include <fstream>
#include <optional>
#include <set>

#include "evaluation/chart.h"
#include "lightstage/errors.h"
#include "lightstage/image_metrics.h"
#include "relight/fit/source_relight.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/ground_truth.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

std::string LedBenchOptions::validate() const {
  if (counts.empty()) return "bench leds: counts: expected at least one dome size";
  for (const int count : counts) {
    if (count < 4 || count > 5000) {
      return "bench leds: counts: expected 4..5000 LEDs, got " + std::to_string(count);
    }
  }
  if (resolution < 4 || resolution > 4096) {
    return "bench leds: resolution: expected 4..4096 pixels, got " + std::to_string(resolution);
  }
  if (repeats < 1)
    return "bench leds: repeats: expected at least 1, got " + std::to_string(repeats);
  if (maps.empty()) return "bench leds: maps: expected at least one environment map";
  return {};
}

namespace {

void write_csv(const fs::path& path, const std::vector<LedBenchRow>& rows) {
  std::ofstream csv(path);
  if (!csv) throw InputError(path.string() + ": cannot write");
  csv << "leds,map,method,relative_rmse,psnr_db,relight_ms,relight_gb_per_s,light_weights_ms,"
         "uncovered_fraction\n";
  for (const LedBenchRow& r : rows) {
    csv << r.leds << ',' << r.map << ',' << r.method << ',' << r.relative_rmse << ',' << r.psnr_db
        << ',' << r.relight_ms << ',' << r.relight_gb_per_s << ',' << r.light_weights_ms << ','
        << r.uncovered_fraction << '\n';
  }
}

void write_charts(const LedBenchOptions& options, const std::vector<LedBenchRow>& rows) {
  std::vector<ChartSeries> speed, error;
  for (const LedBenchRow& r : rows) {  // One series per map and method, in the order they come.
    const std::string name = r.map + (r.method == "cells" ? "" : " + sources");
    size_t m = 0;
    while (m < speed.size() && speed[m].name != name) ++m;
    if (m == speed.size()) {
      speed.push_back({name, {}, {}, {}, true});
      error.push_back({name, {}, {}, {}, true});
    }
    speed[m].x.push_back(r.relight_ms);
    speed[m].y.push_back(r.psnr_db);
    speed[m].point_labels.push_back(std::to_string(r.leds));
    error[m].x.push_back(r.leds);
    error[m].y.push_back(r.relative_rmse);
  }
  const std::string res = std::to_string(options.resolution);
  write_chart(options.out / "leds_psnr_vs_time.png",
              {"Relighting from the field: PSNR vs time per frame (" + res + "x" + res +
                   " px, point labels = LEDs)",
               "relight time per frame, ms", "PSNR vs ground truth, dB", true},
              speed);
  write_chart(
      options.out / "leds_error_vs_count.png",
      {"Relighting error against ground truth vs number of LEDs", "LEDs", "relative RMSE", true},
      error);
}

}  // namespace

LedBenchSummary run_led_bench(const LedBenchOptions& options, const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  const sim::Scene scene = sim::default_scene();
  const std::vector<relight::EnvironmentMap> maps = load_maps(options.maps);
  LedBenchSummary summary;
  for (const int count : options.counts) {
    Stage stage = stage_with_directions(fibonacci_dome_directions(count, -11.5));
    stage.camera.width = stage.camera.height = options.resolution;
    const capture::ReflectanceField field =
        capture_sim_field(stage, scene, options.out / ("session_" + std::to_string(count)),
                          "capture " + std::to_string(count), progress);
    const auto dirs = stage.led_directions();
    const double coverage = max_nearest_neighbour_angle(dirs);
    std::vector<relight::SplitLighting> splits;
    std::set<int> source_leds;
    for (const relight::EnvironmentMap& map : maps) {
      splits.push_back(relight::split_lighting(map, field.lights(), 0.0, coverage, true));
      for (const int led : splits.back().leds()) source_leds.insert(led);
    }
    std::optional<relight::FieldSources> sources;
    const double sources_ms = median_ms(1, [&] {
      sources.emplace(field, capture::whole_field(field),
                      std::vector<int>(source_leds.begin(), source_leds.end()));
    });
    for (size_t m = 0; m < maps.size(); ++m) {
      const relight::EnvironmentMap& map = maps[m];
      sim::GroundTruthOptions gt;
      gt.covered_by_leds = dirs;
      gt.coverage_radius_rad = coverage;
      const Image truth = sim::render_ground_truth(scene, stage.camera, map, gt);
      for (const bool split : {false, true}) {
        if (split && splits[m].sources.empty()) continue;
        LedBenchRow row;
        row.leds = count;
        row.map = fs::path(map.source()).stem().string();
        row.method = split ? "cells + sources" : "cells";
        relight::SplitLighting lighting;
        row.light_weights_ms = median_ms(3, [&] {
          lighting = relight::split_lighting(map, field.lights(), 0.0, coverage, split);
        });
        Image relit;
        row.relight_ms = median_ms(options.repeats, [&] {
          relight::relight_into(field, lighting.weights.irradiance_rgb, relit);
          sources->add(lighting, relit);
        });
        // Reading the field for the sources' normals and LED shadows, once per field.
        if (split) row.light_weights_ms += sources_ms;
        if (count == options.counts.back() && !splits[m].sources.empty()) {
          // The largest dome's images of maps with a source, at the truth's exposure.
          const fs::path png =
              options.out / "compare" / (row.map + (split ? "_sources" : "_cells") + ".png");
          fs::create_directories(png.parent_path());
          write_png_preview(png, relit, auto_exposure_stops(truth));
          summary.comparison.push_back({png, row.map + (split ? ": with sources" : ": LED cells")});
          if (split) {
            const fs::path truth_png = options.out / "compare" / (row.map + "_truth.png");
            write_png_preview(truth_png, truth, auto_exposure_stops(truth));
            summary.comparison.push_back({truth_png, row.map + ": ground truth"});
          }
        }
        const ImageError err = compare_images(relit, truth);
        row.relative_rmse = err.relative_rmse;
        row.psnr_db = err.psnr_db;
        row.relight_gb_per_s = field.bytes() / (row.relight_ms * 1e6);
        row.uncovered_fraction = lighting.weights.uncovered_fraction();
        summary.rows.push_back(row);
      }
    }
  }
  summary.csv = options.out / "leds.csv";
  write_csv(summary.csv, summary.rows);
  write_charts(options, summary.rows);
  return summary;
}

}  // namespace ls::evaluation
