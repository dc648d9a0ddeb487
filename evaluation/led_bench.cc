#include "evaluation/led_bench.h"

#include <algorithm>
#include <array>
#include <fstream>

#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "lightstage/errors.h"
#include "lightstage/image_metrics.h"
#include "relight/lighting/light_cells.h"
#include "relight/sources/map_relight.h"
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
  if (turns < 0 || turns > 360) {
    return "bench leds: turns: expected 0..360, got " + std::to_string(turns);
  }
  return {};
}

namespace {

void write_led_csv(const fs::path& path, const std::vector<LedBenchRow>& rows) {
  std::ofstream csv(path);
  if (!csv) throw InputError(path.string() + ": cannot write");
  csv << "leds,map,method,turns,relative_rmse,psnr_db,relight_ms,relight_gb_per_s,light_weights_ms,"
         "uncovered_fraction\n";
  for (const LedBenchRow& r : rows) {
    csv << r.leds << ',' << r.map << ',' << r.method << ',' << r.turns << ',' << r.relative_rmse
        << ',' << r.psnr_db << ',' << r.relight_ms << ',' << r.relight_gb_per_s << ','
        << r.light_weights_ms << ',' << r.uncovered_fraction << '\n';
  }
}

}  // namespace

void write_led_charts(const fs::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  // One series per map and method, in the order they come; timed rows (turns 0) apart from the
  // medians over turns.
  std::vector<ChartSeries> series;
  for (const std::string& map : table.distinct("map")) {
    for (const std::string& method : table.distinct("method")) {
      series.push_back({.title = map + (method == "cells" ? "" : " + sources"),
                        .where = {{"map", map}, {"method", method}, {"turns", "0"}}});
    }
  }
  Chart speed{.csv = csv,
              .x = "relight_ms",
              .y = "psnr_db",
              .series = series,
              .title = "Relighting from the field: PSNR vs time per frame (point labels: LEDs)",
              .x_label = "relight time per frame, ms",
              .y_label = "PSNR vs ground truth, dB",
              .log_x = true};
  for (ChartSeries& s : speed.series) s.labels.column = "leds";
  write_chart(fs::path(csv).replace_filename("leds_psnr_vs_time.png"), speed);
  Chart error{.csv = csv,
              .x = "leds",
              .y = "relative_rmse",
              .series = series,
              .title = "Relighting error against ground truth vs number of LEDs",
              .x_label = "LEDs",
              .y_label = "relative RMSE",
              .log_x = true};
  write_chart(fs::path(csv).replace_filename("leds_error_vs_count.png"), error);
  std::vector<std::string> turns = table.distinct("turns");
  std::erase(turns, "0");
  if (turns.empty()) return;
  for (ChartSeries& s : error.series) s.where.back().second = turns.front();
  error.title = "The maps with a compact source turned to " + turns.front() +
                " azimuths: median error vs number of LEDs";
  error.y_label = "relative RMSE (median over the turns)";
  write_chart(fs::path(csv).replace_filename("leds_error_vs_count_turned.png"), error);
}

namespace {

// The map turned about the vertical to options.turns azimuths, relit by cells and with sources,
// each against its own ground truth (`unturned_truth` the first turn's, rendered already): the
// median errors (the upper middle one of an even count) over the turns that light what the camera
// sees (a source turned behind the backdrop leaves the truth black: no relative error). None when
// no turn does. relighters[0] relights by cells, [1] with the sources (each turn's LEDs' shadows
// made when first needed).
std::vector<LedBenchRow> turned_rows(const LedBenchOptions& options, const sim::Scene& scene,
                                     const Stage& stage,
                                     const std::array<relight::MapRelighter*, 2>& relighters,
                                     const physics::EnvironmentMap& map, sim::GroundTruthOptions gt,
                                     const Image& unturned_truth) {
  std::vector<LedBenchRow> rows(2);
  std::array<std::vector<ImageError>, 2> errors;
  for (int t = 0; t < options.turns; ++t) {
    gt.rotation_deg = 360.0 * t / options.turns;
    const Image truth =
        t == 0 ? unturned_truth : sim::render_ground_truth(scene, stage.camera, map, gt);
    if (*std::max_element(truth.pixels.begin(), truth.pixels.end()) <= 0) continue;
    for (const bool split : {false, true}) {
      const relight::MapRelit relit = relighters[split ? 1 : 0]->relight(map, gt.rotation_deg);
      errors[split ? 1 : 0].push_back(compare_images(relit.image, truth));
      rows[split ? 1 : 0].uncovered_fraction = relit.lighting.weights.uncovered_fraction();
    }
  }
  if (errors[0].empty()) return {};
  for (const bool split : {false, true}) {
    std::vector<ImageError>& e = errors[split ? 1 : 0];
    LedBenchRow& row = rows[split ? 1 : 0];
    row.map = fs::path(map.source()).stem().string();
    row.method = split ? "cells + sources" : "cells";
    row.turns = int(e.size());
    const auto middle = e.begin() + long(e.size() / 2);
    std::nth_element(e.begin(), middle, e.end(), [](const ImageError& a, const ImageError& b) {
      return a.relative_rmse < b.relative_rmse;
    });
    row.relative_rmse = middle->relative_rmse;
    row.psnr_db = middle->psnr_db;
  }
  return rows;
}

}  // namespace

LedBenchSummary run_led_bench(const LedBenchOptions& options, const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  const sim::Scene scene = sim::default_scene();
  const std::vector<physics::EnvironmentMap> maps = load_maps(options.maps);
  LedBenchSummary summary;
  for (const int count : options.counts) {
    Stage stage = stage_with_directions(fibonacci_dome_directions(count, -11.5));
    stage.camera.width = stage.camera.height = options.resolution;
    const capture::ReflectanceField field =
        capture_sim_field(stage, scene, options.out / ("session_" + std::to_string(count)),
                          "capture " + std::to_string(count), progress);
    const auto dirs = stage.led_directions();
    const double coverage = max_nearest_neighbour_angle(dirs);
    relight::MapRelightOptions by_cells;
    by_cells.coverage_rad = coverage;
    by_cells.bright_sources = false;
    relight::MapRelightOptions with_sources = by_cells;
    with_sources.bright_sources = true;
    relight::MapRelighter cells(field, by_cells), sources(field, with_sources);
    const std::array<relight::MapRelighter*, 2> relighters{&cells, &sources};
    std::vector<relight::SplitLighting> splits;
    splits.reserve(maps.size());
    for (const physics::EnvironmentMap& map : maps) splits.push_back(sources.lighting(map, 0.0));
    // Reading the field for the sources' normals, the scene's shape and the LEDs' shadows, once.
    const double sources_ms = median_ms(1, [&] { sources.prepare(splits); });
    for (size_t m = 0; m < maps.size(); ++m) {
      const physics::EnvironmentMap& map = maps[m];
      sim::GroundTruthOptions gt;
      gt.covered_by_leds = dirs;
      gt.coverage_radius_rad = coverage;
      const Image truth = sim::render_ground_truth(scene, stage.camera, map, gt);
      for (const bool split : {false, true}) {
        if (split && splits[m].sources.empty()) continue;
        relight::MapRelighter& relighter = *relighters[split ? 1 : 0];
        LedBenchRow row;
        row.leds = count;
        row.map = fs::path(map.source()).stem().string();
        row.method = split ? "cells + sources" : "cells";
        relight::SplitLighting lighting;
        row.light_weights_ms = median_ms(3, [&] { lighting = relighter.lighting(map, 0.0); });
        Image relit;
        row.relight_ms = median_ms(options.repeats, [&] { relighter.render(lighting, relit); });
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
      if (options.turns > 0 && !splits[m].sources.empty()) {
        for (LedBenchRow& row : turned_rows(options, scene, stage, relighters, map, gt, truth)) {
          row.leds = count;
          summary.rows.push_back(std::move(row));
        }
      }
    }
  }
  summary.csv = options.out / "leds.csv";
  write_led_csv(summary.csv, summary.rows);
  write_led_charts(summary.csv);
  return summary;
}

}  // namespace ls::evaluation
