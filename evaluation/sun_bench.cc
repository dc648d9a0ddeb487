#include "evaluation/sun_bench.h"

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <optional>

#include "evaluation/chart.h"
#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/image_metrics.h"
#include "relight/sources/map_relight.h"
#include "sim/ground_truth.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// A black map with a uniform disc toward `centre` giving unit irradiance at normal incidence,
// each pixel the mean of 8 x 8 samples (so the map's integral is the disc's).
relight::EnvironmentMap disc_map(const Eigen::Vector3d& centre, double radius_deg) {
  const int width = 1024, height = 512;
  const double cos_r = std::cos(radius_deg * kDeg);
  const double radiance = 1.0 / (std::numbers::pi * std::pow(std::sin(radius_deg * kDeg), 2));
  Image image(width, height, 3);
  // Only pixels whose centre is within a pixel's size (0.35 deg) of the disc can hold part of it.
  const double cos_near = std::cos((radius_deg + 1.0) * kDeg);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      if (relight::EnvironmentMap::direction((x + 0.5) / width, (y + 0.5) / height).dot(centre) <
          cos_near) {
        continue;
      }
      int inside = 0;
      for (int sy = 0; sy < 8; ++sy) {
        for (int sx = 0; sx < 8; ++sx) {
          inside += relight::EnvironmentMap::direction((x + (sx + 0.5) / 8) / width,
                                                       (y + (sy + 0.5) / 8) / height)
                        .dot(centre) >= cos_r;
        }
      }
      for (int c = 0; c < 3; ++c) {
        image.pixels[(size_t(y) * width + x) * 3 + c] = float(radiance * inside / 64.0);
      }
    }
  }
  return relight::EnvironmentMap(std::move(image), "disc");
}

void write_outputs(const SunBenchOptions& options, const SunBenchSummary& summary) {
  std::ofstream csv(summary.csv);
  if (!csv) throw InputError(summary.csv.string() + ": cannot write");
  csv << "path,position,angle_to_nearest_led_deg,cells_rmse,sources_rmse,flows_rmse,"
         "exact_visibility_rmse,cells_ms,sources_ms,flows_ms\n";
  for (const SunBenchRow& r : summary.rows) {
    csv << r.path << ',' << r.position << ',' << r.angle_to_nearest_led_deg << ',' << r.cells_rmse
        << ',' << r.sources_rmse << ',' << r.flows_rmse << ',' << r.exact_visibility_rmse << ','
        << r.cells_ms << ',' << r.sources_ms << ',' << r.flows_ms << '\n';
  }
  for (const std::string path : {"sweep", "turn"}) {
    ChartSeries cells{"LED cells (today)", {}, {}, {}, true};
    ChartSeries flows{"source: flows alone", {}, {}, {}, true};
    ChartSeries sources{"source: flows + shape", {}, {}, {}, true};
    ChartSeries exact{"exact visibility (sim)", {}, {}, {}, true};
    for (const SunBenchRow& r : summary.rows) {
      if (r.path != path) continue;
      for (ChartSeries* s : {&cells, &flows, &sources, &exact}) s->x.push_back(r.position);
      cells.y.push_back(r.cells_rmse);
      flows.y.push_back(r.flows_rmse);
      sources.y.push_back(r.sources_rmse);
      exact.y.push_back(r.exact_visibility_rmse);
    }
    const bool sweep = path == "sweep";
    write_chart(
        options.out / ("sun_" + path + ".png"),
        {sweep ? "A small source swept from an LED (0) to the middle of three LEDs (1)"
               : "A small source turned through a full circle about the vertical",
         sweep ? "position between the LED and the middle of its triangle" : "azimuth, degrees",
         "relative RMSE against ground truth", false},
        {cells, flows, sources, exact});
  }
  ChartSeries cells{"LED cells (today)", {}, {}, {}, false};
  ChartSeries flows{"source: flows alone", {}, {}, {}, false};
  ChartSeries sources{"source: flows + shape", {}, {}, {}, false};
  for (const SunBenchRow& r : summary.rows) {
    cells.x.push_back(r.cells_ms);
    cells.y.push_back(r.cells_rmse);
    flows.x.push_back(r.flows_ms);
    flows.y.push_back(r.flows_rmse);
    sources.x.push_back(r.sources_ms);
    sources.y.push_back(r.sources_rmse);
  }
  write_chart(
      options.out / "sun_error_vs_time.png",
      {"Small source, " + std::to_string(options.resolution) +
           " px: error vs. time per frame (setup " + std::to_string(int(summary.flows_setup_ms)) +
           " ms, with the shape " + std::to_string(int(summary.sources_setup_ms)) + ")",
       "relight time per frame, ms", "relative RMSE against ground truth", false},
      {cells, flows, sources});
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
  const double el = options.elevation_deg * kDeg;
  const Eigen::Vector3d aim(std::cos(el) * std::cos(30 * kDeg), std::sin(el),
                            std::cos(el) * std::sin(30 * kDeg));
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
    places.push_back({"turn", azimuth, relight::rotate_about_y(aim, azimuth)});
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
  std::vector<relight::EnvironmentMap> maps;
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
    row.angle_to_nearest_led_deg = index.nearest_angle(places[i].dir) / kDeg;
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
                                                           options.radius_deg * kDeg);
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
