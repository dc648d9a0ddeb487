#pragma once
// `lightstage bench material`: the captured materials out of lightstage, measured for speed and
// accuracy. The demo scene is captured on the simulated stage, fitted, converted to GGX
// metallic-roughness (relight/material/ggx_conversion.h) and exported as glTF; Blender (Cycles,
// CPU) renders the glTF on its plane under each map and lightstage renders the fitted maps on the
// same plane (relight/material/shape_render.h). Per bin of the conversion's reported error: the two
// renders' difference over its pixels (CSV and a chart); per map: the images' mean difference;
// the conversion's and the renders' times.
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"

namespace ls::evaluation {

struct MaterialBenchOptions {
  std::filesystem::path out = "bench_out";
  int resolution = 64;                      // The capture's and the renders' width and height.
  int samples = 128;                        // Cycles samples per pixel.
  std::vector<std::filesystem::path> maps;  // Environment maps.
  std::filesystem::path blender_script;     // tests/tools/blender_render_gltf.py.
  std::string validate() const;
};

struct MaterialBenchRow {
  std::string map;
  double mean_difference = 0;  // Sum |Blender - lightstage| / sum lightstage over the plane.
  double lightstage_s = 0, blender_s = 0;
};

struct MaterialBenchSummary {
  std::vector<MaterialBenchRow> rows;
  int pixels = 0;
  double conversion_s = 0, median_error = 0, p95_error = 0;
  std::filesystem::path csv, chart;
};

MaterialBenchSummary run_material_bench(const MaterialBenchOptions& options,
                                        const ProgressFn& progress = {});

}  // namespace ls::evaluation
