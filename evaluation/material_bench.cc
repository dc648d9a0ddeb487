#include "evaluation/material_bench.h"

#include <cmath>
#include <fstream>

#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "relight/fit/fit.h"
#include "relight/material/ggx_conversion.h"
#include "relight/material/material_export.h"
#include "relight/material/shape_render.h"
#include "relight/material/surface_mesh.h"
#include "sim/scene.h"

namespace ls::evaluation {
namespace fs = std::filesystem;

std::string MaterialBenchOptions::validate() const {
  if (resolution < 8 || resolution > 1024) return "--resolution: expected 8 to 1024";
  if (samples < 1) return "--samples: expected at least 1";
  if (maps.empty()) return "no environment maps";
  return {};
}

MaterialBenchSummary run_material_bench(const MaterialBenchOptions& options,
                                        const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  const fs::path dir = options.out / "material";
  fs::create_directories(dir);
  Stage stage = default_stage();
  stage.camera.width = stage.camera.height = options.resolution;
  const capture::ReflectanceField field =
      capture_sim_field(stage, sim::default_scene(), dir / "session", "capture", progress);
  report(progress, "fit", 0, 1);
  const relight::ModelMaps maps = relight::fit_models(field, relight::FitOptions{});
  report(progress, "fit", 1, 1);

  MaterialBenchSummary summary;
  relight::GgxConversion material;
  summary.conversion_s = median_ms(3, [&] { material = relight::convert_to_ggx(maps); }) / 1e3;
  summary.pixels = material.pixels;
  summary.median_error = material.median_error;
  summary.p95_error = material.p95_error;
  // The plane 2 x 2 in the camera's 2.4-tall view, as render --shape plane puts it.
  const relight::MaterialExport files = relight::write_gltf(
      material, dir / "gltf", "demo", relight::plane_mesh(maps.maps.width, maps.maps.height, 2.0));

  summary.csv = options.out / "material.csv";
  std::ofstream csv(summary.csv);
  csv << "map,conversion_error,blender_difference,pixels\n";
  const std::vector<physics::EnvironmentMap> maps_loaded = load_maps(options.maps);
  const int n = options.resolution;
  for (size_t k = 0; k < options.maps.size(); ++k) {
    const std::string name = options.maps[k].stem().string();
    report(progress, "render " + name, 0, 2);
    MaterialBenchRow row{name};
    relight::ShapeRenderOptions plane;
    plane.shape = relight::Shape::kPlane;
    plane.width = plane.height = n;
    relight::EnvironmentSampling sampling;
    sampling.directions_width = 128;
    Image own;
    row.lightstage_s =
        median_ms(3,
                  [&] {
                    own = relight::render_on_shape(
                        maps, relight::LightingForModels::environment(maps_loaded[k], 0, sampling),
                        plane);
                  }) /
        1e3;
    report(progress, "render " + name, 1, 2);
    const fs::path rendered = dir / (name + ".blender.exr");
    row.blender_s =
        run_process({"blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python",
                     options.blender_script.string(), "--", files.document.string(),
                     options.maps[k].string(), rendered.string(), std::to_string(options.samples),
                     std::to_string(n)},
                    dir / (name + ".blender.log"))
            .seconds;
    report(progress, "render " + name, 2, 2);
    const Image blender = read_image(rendered);
    write_exr(dir / (name + ".lightstage.exr"), own);
    // Per bin of the conversion's error at the pixel's texel: the two renders' mean absolute
    // difference over lightstage's mean (per pixel, Cycles' noise and dark pixels swamp it).
    constexpr double kBinEdges[] = {0.0, 0.01, 0.05, 0.1, 0.15, 0.2, 1e9};
    constexpr int kBins = 6;
    double bin_diff[kBins] = {}, bin_sum[kBins] = {}, bin_error[kBins] = {};
    int bin_pixels[kBins] = {};
    double diff = 0, sum = 0;
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const size_t i = size_t(y) * n + x;
        if (own.pixels[i * 4 + 3] < 1) continue;
        double pixel_diff = 0, pixel_sum = 0;
        for (int c = 0; c < 3; ++c) {
          pixel_diff += std::abs(blender.pixels[i * blender.channels + c] - own.pixels[i * 4 + c]);
          pixel_sum += own.pixels[i * 4 + c];
        }
        diff += pixel_diff;
        sum += pixel_sum;
        // The texel the pixel shows: the plane spans 2 of the view's 2.4 units.
        const double u = ((x + 0.5) / n * 2.4 - 0.2) / 2.0, v = ((y + 0.5) / n * 2.4 - 0.2) / 2.0;
        const int tx = std::clamp(int(u * material.width), 0, material.width - 1);
        const int ty = std::clamp(int(v * material.height), 0, material.height - 1);
        const double error = material.error.pixels[size_t(ty) * material.width + tx];
        int bin = 0;
        while (bin + 1 < kBins && error >= kBinEdges[bin + 1]) ++bin;
        bin_diff[bin] += pixel_diff;
        bin_sum[bin] += pixel_sum;
        bin_error[bin] += error;
        ++bin_pixels[bin];
      }
    }
    for (int b = 0; b < kBins; ++b) {
      if (bin_pixels[b] == 0 || !(bin_sum[b] > 0)) continue;
      csv << name << "," << bin_error[b] / bin_pixels[b] << "," << bin_diff[b] / bin_sum[b] << ","
          << bin_pixels[b] << "\n";
    }
    row.mean_difference = diff / sum;
    summary.rows.push_back(row);
  }
  csv.close();
  Chart chart;
  chart.csv = summary.csv;
  chart.x = "conversion_error";
  chart.y = "blender_difference";
  std::vector<std::string> names;
  for (const MaterialBenchRow& row : summary.rows) names.push_back(row.map);
  chart.series = series_by("map", names);
  chart.title = "Blender's render of the exported glTF against lightstage's of the fitted maps";
  chart.x_label = "the conversion's reported error (relative RMS), mean over the pixels of a bin";
  chart.y_label = "sum |Blender - lightstage| / sum lightstage over those pixels";
  summary.chart = options.out / "material_difference_vs_conversion_error.png";
  write_chart(summary.chart, chart);
  return summary;
}

}  // namespace ls::evaluation
