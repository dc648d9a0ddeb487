#include "evaluation/sun_bench.h"

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <optional>

#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "lightstage/angles.h"
#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/image_metrics.h"
#include "relight/sources/map_relight.h"
#include "sim/ground_truth.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

namespace {

// A black map with a uniform disc toward `centre` giving unit irradiance at normal incidence,
// each pixel the mean of 8 x 8 samples (so the map's integral is the disc's).
physics::EnvironmentMap disc_map(const Eigen::Vector3d& centre, double radius_deg) {
  const int width = 1024, height = 512;
  const double cos_r = std::cos(radius_deg * kDegToRad);
  const double radiance = 1.0 / (std::numbers::pi * std::pow(std::sin(radius_deg * kDegToRad), 2));
  Image image(width, height, 3);
  // Only pixels whose centre is within a pixel's size (0.35 deg) of the disc can hold part of it.
  const double cos_near = std::cos((radius_deg + 1.0) * kDegToRad);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      if (physics::EnvironmentMap::direction((x + 0.5) / width, (y + 0.5) / height).dot(centre) <
          cos_near) {
        continue;
      }
      int inside = 0;
      for (int sy = 0; sy < 8; ++sy) {
        for (int sx = 0; sx < 8; ++sx) {
          inside += physics::EnvironmentMap::direction((x + (sx + 0.5) / 8) / width,
                                                       (y + (sy + 0.5) / 8) / height)
                        .dot(centre) >= cos_r;
        }
      }
      for (int c = 0; c < 3; ++c) {
        image.pixels[(size_t(y) * width + x) * 3 + c] = float(radiance * inside / 64.0);
      }
    }
  }
  return physics::EnvironmentMap(std::move(image), "disc");
}

}  // namespace

void write_sun_charts(const fs::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  // The methods are columns (NAME_rmse, NAME_ms): one series each.
  const std::pair<const char*, std::string> methods[] = {{"LED cells", "cells"},
                                                         {"source: flows alone", "flows"},
                                                         {"source: flows + shape", "sources"},
                                                         {"exact visibility (sim)", "exact"}};
  for (const std::string& path : table.distinct("path")) {
    const bool sweep = path == "sweep";
    Chart chart{
        .csv = csv,
        .x = "position",
        .title = sweep ? "A small source swept from an LED (0) to the middle of three LEDs (1)"
                       : "A small source turned through a full circle about the vertical",
        .x_label =
            sweep ? "position between the LED and the middle of its triangle" : "azimuth, degrees",
        .y_label = "relative RMSE against ground truth"};
    for (const auto& [title, name] : methods) {
      const std::string y = name == "exact" ? "exact_visibility_rmse" : name + "_rmse";
      chart.series.push_back({.title = title, .where = {{"path", path}}, .y = y});
    }
    write_chart(fs::path(csv).replace_filename("sun_" + path + ".png"), chart);
  }
  std::string about;  // Older files lack the size and the set-up times.
  if (table.has("sources_setup_ms") && !table.rows.empty()) {
    const auto& row = table.rows[0];
    const auto whole = [&](const char* column) {
      return std::to_string(std::lround(std::stod(row[table.column(column)])));
    };
    about = ", " + row[table.column("resolution")] + " px (set-up " + whole("flows_setup_ms") +
            " ms, with the shape " + whole("sources_setup_ms") + ")";
  }
  // Time is measured per method (none for the exact visibility): each series its own x.
  Chart by_time{.csv = csv,
                .title = "Small source: error vs. time per frame" + about,
                .x_label = "relight time per frame, ms",
                .y_label = "relative RMSE against ground truth",
                .log_x = true,
                .lines = false};
  for (const auto& [title, name] : methods) {
    if (name == "exact") continue;
    by_time.series.push_back({.title = title, .x = name + "_ms", .y = name + "_rmse"});
  }
  write_chart(fs::path(csv).replace_filename("sun_error_vs_time.png"), by_time);
}

namespace {

void write_outputs(const SunBenchOptions& options, const SunBenchSummary& summary) {
  std::ofstream csv(summary.csv);
  if (!csv) throw InputError(summary.csv.string() + ": cannot write");
  csv << "path,position,angle_to_nearest_led_deg,cells_rmse,sources_rmse,flows_rmse,"
         "exact_visibility_rmse,cells_ms,sources_ms,flows_ms,resolution,flows_setup_ms,"
         "sources_setup_ms\n";
  for (const SunBenchRow& r : summary.rows) {
    csv << r.path << ',' << r.position << ',' << r.angle_to_nearest_led_deg << ',' << r.cells_rmse
        << ',' << r.sources_rmse << ',' << r.flows_rmse << ',' << r.exact_visibility_rmse << ','
        << r.cells_ms << ',' << r.sources_ms << ',' << r.flows_ms << ',' << options.resolution
        << ',' << summary.flows_setup_ms << ',' << summary.sources_setup_ms << '\n';
  }
  csv.close();
  write_sun_charts(summary.csv);
}

}  // namespace

std::string SunBenchOptions::validate() const {
  if (resolution < 8 || resolution > 2048) return "bench sun: resolution: expected 8..2048";
  if (!(radius_deg > 0 && radius_deg <= 5)) return "bench sun: radius: expected (0, 5] degrees";
  if (!(elevation_deg >= 5 && elevation_deg <= 85)) return "bench sun: elevation: expected 5..85";
  if (sweep_steps < 1 || turn_steps < 1) return "bench sun: steps: expected at least 1";
  if (repeats < 1) return "bench sun: repeats: expected at least 1";
  return {};
}

SunBenchSummary run_sun_bench(const SunBenchOptions& options, const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  Stage stage = default_stage();
  stage.camera.width = stage.camera.height = options.resolution;
  const sim::Scene scene = sim::default_scene();
  const capture::ReflectanceField field =
      capture_sim_field(stage, scene, options.out / "session_sun", "capture", progress);
  const std::vector<Eigen::Vector3d> dirs = stage.led_directions();
  const double coverage = max_nearest_neighbour_angle(dirs);

  // The sweep: from the LED nearest the given elevation toward the camera's right to the middle
  // of a triangle of LEDs around it.
  const double el = options.elevation_deg * kDegToRad;
  const Eigen::Vector3d aim(std::cos(el) * std::cos(30 * kDegToRad), std::sin(el),
                            std::cos(el) * std::sin(30 * kDegToRad));
  const DirectionIndex index(dirs);
  const int start_led = index.within(aim, std::numbers::pi).front();
  const Eigen::Vector3d& start = dirs[size_t(start_led)];
  // A direction just off the LED, toward the aim, names the triangle the sweep crosses.
  const Eigen::Vector3d nudged =
      (start + 0.05 * (aim - start + 0.1 * start.cross(Eigen::Vector3d::UnitY())).normalized())
          .normalized();
  const std::optional<relight::LedTriangle> triangle =
      relight::led_triangle(dirs, {}, nudged, coverage);
  LS_CHECK(triangle.has_value(), "bench sun: no LED triangle near the start LED");
  Eigen::Vector3d middle(0, 0, 0);
  for (const int led : triangle->leds) middle += dirs[size_t(led)];
  middle.normalize();
  // Positions: (path, position, direction).
  struct Place {
    std::string path;
    double position;
    Eigen::Vector3d dir;
  };
  std::vector<Place> places;
  for (int i = 0; i <= options.sweep_steps; ++i) {
    const double t = double(i) / options.sweep_steps;
    places.push_back({"sweep", t, ((1 - t) * start + t * middle).normalized()});
  }
  for (int i = 0; i < options.turn_steps; ++i) {
    const double azimuth = 360.0 * i / options.turn_steps;
    places.push_back({"turn", azimuth, physics::rotate_about_y(aim, azimuth)});
  }
  // By cells alone; the source split off with its shadows by the flows and the scene's shape
  // (as `relight` does), and by the flows alone.
  relight::MapRelightOptions by_cells;
  by_cells.coverage_rad = coverage;
  by_cells.bright_sources = false;
  relight::MapRelightOptions with_shape = by_cells;
  with_shape.bright_sources = true;
  relight::MapRelightOptions flows_alone = with_shape;
  flows_alone.source_geometry = false;
  relight::MapRelighter cells(field, by_cells), sources(field, with_shape),
      flows(field, flows_alone);
  std::vector<relight::SplitLighting> splits;
  std::vector<physics::EnvironmentMap> maps;
  for (const Place& place : places) {
    maps.push_back(disc_map(place.dir, options.radius_deg));
    splits.push_back(sources.lighting(maps.back(), 0.0));
  }
  SunBenchSummary summary;
  summary.sources_setup_ms = median_ms(1, [&] { sources.prepare(splits); });
  summary.flows_setup_ms = median_ms(1, [&] { flows.prepare(splits); });
  for (size_t i = 0; i < places.size(); ++i) {
    SunBenchRow row;
    row.path = places[i].path;
    row.position = places[i].position;
    row.angle_to_nearest_led_deg = index.nearest_angle(places[i].dir) / kDegToRad;
    const relight::SplitLighting by_cells_lighting = cells.lighting(maps[i], 0.0);
    Image relit_cells, relit_sources, relit_flows;
    row.cells_ms =
        median_ms(options.repeats, [&] { cells.render(by_cells_lighting, relit_cells); });
    row.sources_ms = median_ms(options.repeats, [&] { sources.render(splits[i], relit_sources); });
    row.flows_ms = median_ms(options.repeats, [&] { flows.render(splits[i], relit_flows); });
    sim::GroundTruthOptions gt;
    gt.directions_width = 256;  // 0.7-degree quadrature: the 2-degree disc's penumbrae resolved.
    gt.covered_by_leds = dirs;
    gt.coverage_radius_rad = coverage;
    const Image truth = sim::render_ground_truth(scene, stage.camera, maps[i], gt);
    row.cells_rmse = compare_images(relit_cells, truth).relative_rmse;
    row.sources_rmse = compare_images(relit_sources, truth).relative_rmse;
    row.flows_rmse = compare_images(relit_flows, truth).relative_rmse;
    // The same render with the visibility traced in the scene: the shading's part of the error.
    const Image visibility = sim::render_source_visibility(scene, stage.camera, places[i].dir,
                                                           options.radius_deg * kDegToRad);
    Image relit_exact;
    sources.render(splits[i], relit_exact, {&visibility});
    row.exact_visibility_rmse = compare_images(relit_exact, truth).relative_rmse;
    // Every position's images at the truth's exposure: what the numbers mean.
    char stem[64];
    std::snprintf(stem, sizeof stem, "%s_%07.3f", row.path.c_str(), row.position);
    const fs::path frames = options.out / "sun_frames";
    fs::create_directories(frames);
    const double stops = auto_exposure_stops(truth);
    write_png_preview(frames / (std::string(stem) + "_cells.png"), relit_cells, stops);
    write_png_preview(frames / (std::string(stem) + "_sources.png"), relit_sources, stops);
    write_png_preview(frames / (std::string(stem) + "_truth.png"), truth, stops);
    summary.rows.push_back(row);
    report(progress, "sun positions", long(i + 1), long(places.size()), places[i].path);
  }
  summary.csv = options.out / "sun.csv";
  write_outputs(options, summary);
  return summary;
}

}  // namespace ls::evaluation
