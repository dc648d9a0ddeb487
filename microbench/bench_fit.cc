// Per-pixel model fitting throughput (fitted pixels per second) per candidate model set, and the
// time to render fitted models under an environment map against field relighting of the same size.
//   ./build/microbench/bench_fit --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <map>
#include <memory>
#include <random>
#include <vector>

#include "capture/field.h"
#include "lightstage/stage.h"
#include "physics/envmap.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "relight/fit/normals.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/noisy_field.h"
#include "sim/scene.h"

namespace {

using ls::relight::FitModel;

int threads_for(int arg) { return arg > 0 ? arg : int(tbb::info::default_concurrency()); }

ls::Stage bench_stage(int size) {
  ls::Stage stage = ls::default_stage();  // 151 LEDs.
  stage.camera.width = stage.camera.height = size;
  stage.camera.fov_y_deg = 0.0;  // Orthographic, as the fit assumes by default.
  stage.camera.ortho_height_m = 1.0;
  return stage;
}

// The ideal field of `scene` plus the sensor noise of the fit's default noise model.
ls::capture::ReflectanceField sim_field(const ls::Stage& stage, const ls::sim::Scene& scene) {
  return ls::sim::render_noisy_field(stage, scene, ls::relight::NoiseModel{}.as_field_noise(),
                                     /*seed=*/1);
}

// One sphere filling the view, of the material the model describes (kNone: the demo scene).
ls::sim::Scene scene_for(FitModel model) {
  if (model == FitModel::kNone) return ls::sim::default_scene();
  ls::sim::Scene scene;
  ls::sim::SceneMaterial m;
  m.base.albedo = {0.6, 0.45, 0.3};
  if (model == FitModel::kOrenNayar) {
    m.base.diffuse = ls::physics::brdf::DiffuseModel::kOrenNayar;
    m.base.sigma_rad = 0.5;
  }
  if (model == FitModel::kLambertTorranceSparrow) {
    m.base.specular = ls::physics::brdf::SpecularModel::kTorranceSparrow;
    m.base.ks = {0.35, 0.35, 0.35};
  }
  if (model == FitModel::kLambertPhong) {
    m.base.specular = ls::physics::brdf::SpecularModel::kPhong;
    m.base.ks = {0.35, 0.35, 0.35};
  }
  scene.materials.push_back(m);
  scene.spheres.push_back({Eigen::Vector3d(0, 0, 0), 0.48, 0});
  return scene;
}

// Candidates: Lambert always, plus the one model (kNone: the default set, Lambert + Oren-Nayar +
// Torrance-Sparrow).
ls::relight::FitOptions options_for(FitModel model) {
  ls::relight::FitOptions options;
  if (model == FitModel::kNone) return options;
  options.fit_oren_nayar = model == FitModel::kOrenNayar;
  options.fit_torrance_sparrow = model == FitModel::kLambertTorranceSparrow;
  options.fit_phong = model == FitModel::kLambertPhong;
  return options;
}

struct FitInput {
  ls::capture::ReflectanceField field;
  ls::relight::NormalMap normals;
};

const FitInput& fit_input(FitModel model) {
  static std::map<FitModel, std::unique_ptr<FitInput>> inputs;
  auto& slot = inputs[model];
  if (!slot) {
    slot = std::make_unique<FitInput>();
    slot->field = sim_field(bench_stage(48), scene_for(model));
    slot->normals = ls::relight::estimate_normals(slot->field, options_for(model).normals);
  }
  return *slot;
}

// Args: model (FitModel as int; 0 = the default candidate set on the demo scene), threads.
void BM_Fit(benchmark::State& state) {
  const FitModel model = FitModel(int(state.range(0)));
  const int threads = threads_for(int(state.range(1)));
  const FitInput& input = fit_input(model);
  const ls::relight::FitOptions options = options_for(model);
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  long fitted = 0;
  for (auto _ : state) {
    const ls::relight::ModelMaps maps =
        ls::relight::fit_models(input.field, input.normals, options);
    fitted += maps.summary.fitted;
    benchmark::DoNotOptimize(maps.maps.pixels.data());
  }
  state.counters["threads"] = threads;
  state.counters["fitted_px_per_s"] =
      benchmark::Counter(double(fitted), benchmark::Counter::kIsRate);
  const char* labels[5] = {"lambert, oren-nayar, lambert+torrance-sparrow (demo scene)", "lambert",
                           "lambert, oren-nayar", "lambert, lambert+torrance-sparrow",
                           "lambert, lambert+phong"};
  state.SetLabel(labels[int(model)]);
}
BENCHMARK(BM_Fit)
    ->ArgsProduct({{1, 2, 3, 4, 0}, {1, 0}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(1);

// Maps of size x size tiled from the fit of the demo scene at 48x48 (rendering cost depends on
// each pixel's model, not on where it sits), and the demo scene's map.
const ls::relight::ModelMaps& tiled_maps(int size) {
  static std::map<int, std::unique_ptr<ls::relight::ModelMaps>> cache;
  auto& slot = cache[size];
  if (!slot) {
    const FitInput& input = fit_input(FitModel::kNone);
    const ls::relight::ModelMaps tile =
        ls::relight::fit_models(input.field, input.normals, options_for(FitModel::kNone));
    slot = std::make_unique<ls::relight::ModelMaps>();
    slot->maps = ls::Image(size, size, tile.maps.channels);
    slot->maps.channel_names = tile.maps.channel_names;
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        for (int c = 0; c < tile.maps.channels; ++c) {
          slot->maps.at(x, y, c) = tile.maps.at(x % tile.maps.width, y % tile.maps.height, c);
        }
      }
    }
  }
  return *slot;
}

ls::physics::EnvironmentMap studio_map() {
  ls::Image image(512, 256, 3, 0.05f);
  // A bright band overhead and a warm key light: enough structure for non-trivial sums.
  for (int y = 20; y < 60; ++y) {
    for (int x = 300; x < 360; ++x) {
      image.at(x, y, 0) = 8.0f;
      image.at(x, y, 1) = 7.0f;
      image.at(x, y, 2) = 5.0f;
    }
  }
  return ls::physics::EnvironmentMap(image);
}

// Args: maps size, lighting (0: LED cells of the 151-LED dome; N > 0: N-wide lat-long grid),
// threads.
void BM_RenderModels(benchmark::State& state) {
  const int size = int(state.range(0));
  const int grid = int(state.range(1));
  const int threads = threads_for(int(state.range(2)));
  const ls::relight::ModelMaps& maps = tiled_maps(size);
  const ls::physics::EnvironmentMap map = studio_map();
  const std::vector<Eigen::Vector3d> dirs = bench_stage(8).led_directions();
  const ls::relight::LightingForModels lighting =
      grid > 0 ? ls::relight::LightingForModels::environment(map, 0.0, {grid})
               : ls::relight::LightingForModels::led_cells(
                     dirs, ls::relight::integrate_environment(map, dirs));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  for (auto _ : state) {
    ls::Image out = ls::relight::render_models(maps, lighting);
    benchmark::DoNotOptimize(out.pixels.data());
  }
  state.counters["threads"] = threads;
  state.counters["directions"] = double(lighting.dirs_in_stage.size());
}
BENCHMARK(BM_RenderModels)
    ->ArgsProduct({{256}, {0, 32, 64}, {1, 0}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(0.3);

// Field relighting of the same size (151 LEDs), for comparison with BM_RenderModels.
void BM_RelightField(benchmark::State& state) {
  const int size = int(state.range(0));
  const int threads = threads_for(int(state.range(1)));
  static std::map<int, std::unique_ptr<ls::capture::ReflectanceField>> fields;
  auto& slot = fields[size];
  if (!slot) {
    std::vector<ls::capture::FieldLight> lights(bench_stage(8).leds.size());
    slot = std::make_unique<ls::capture::ReflectanceField>(size, size, lights);
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> value(0.0f, 1.0f);
    float* p = slot->pixel(0, 0);
    for (size_t i = 0; i < slot->values().size(); ++i) p[i] = value(rng);
  }
  std::vector<float> e(3 * slot->num_lights(), 0.01f);
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  ls::Image out;
  for (auto _ : state) {
    ls::relight::relight_into(*slot, e, out);
    benchmark::DoNotOptimize(out.pixels.data());
  }
  state.counters["threads"] = threads;
}
BENCHMARK(BM_RelightField)
    ->ArgsProduct({{256}, {1, 0}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(0.3);

}  // namespace

BENCHMARK_MAIN();
