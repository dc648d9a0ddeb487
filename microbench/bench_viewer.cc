// Viewer frame time on the GPU: relighting a 512 x 512 x 150-LED field per source (field
// in half and in float, PCA k = 16, fitted models under 512 and 2048 distant lights, exact and
// through the prefiltered environment), one frame = weights upload + draw + glFinish, in a hidden
// GlWindow. Needs a display:
//   xvfb-run -a -s "-screen 0 1280x720x24" build/microbench/bench_viewer   (llvmpipe)
// The upload itself (once per source) is timed too (BM_UploadField).
// Compact sources: the field on the CPU under sky_sun.exr turning by 0.1 deg a frame, the sun split
// off and rendered at its true direction (BM_FieldSunRotationOnCpu, with/without the split), and
// the first frame with a sun (photometric-stereo normals, then the sun's LED shadows and flows);
// the sun's shadows cast by the recovered shape (BM_FieldSunShapeOnCpu).
#include <benchmark/benchmark.h>

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <numbers>

#include "capture/field.h"
#include "lightstage/stage.h"
#include "physics/envmap.h"
#include "relight/compact/pca_field.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "viewer/cpu_sources.h"
#include "viewer/gl_window.h"
#include "viewer/gpu_relight.h"
#include "viewer/view_lighting.h"

namespace {

constexpr int kSize = 512;
constexpr int kLeds = 150;

ls::viewer::GlWindow& window() {
  static auto* w = [] {
    auto* created = new ls::viewer::GlWindow(256, 256, "bench_viewer", false);
    std::cout << "renderer: " << created->renderer() << std::endl;
    return created;
  }();
  return *w;
}

Eigen::Vector3d normal_at(int x, int y) {
  return Eigen::Vector3d(std::sin(x * 0.01), std::cos(y * 0.013), 1.5).normalized();
}

// A cheap analytic field (what a frame costs does not depend on the values): Lambertian shading
// of a smoothly varying normal with a colour ramp, R = albedo / pi * max(0, n . d_l).
const ls::capture::ReflectanceField& field() {
  static std::unique_ptr<ls::capture::ReflectanceField> f;
  if (!f) {
    std::vector<ls::capture::FieldLight> lights;
    int id = 0;
    for (const Eigen::Vector3d& d : ls::fibonacci_dome_directions(kLeds, 10.0)) {
      lights.push_back({id++, d, true});
    }
    f = std::make_unique<ls::capture::ReflectanceField>(kSize, kSize, lights);
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        const Eigen::Vector3d n = normal_at(x, y);
        float* v = f->pixel(x, y);
        for (int l = 0; l < kLeds; ++l) {
          const double shading = std::max(0.0, n.dot(lights[l].dir_in_stage)) / std::numbers::pi;
          for (int c = 0; c < 3; ++c) v[l * 3 + c] = float(shading * (0.3 + 0.2 * c));
        }
      }
    }
  }
  return *f;
}

// Every LED lit (the worst case: nothing skipped), unequal weights.
ls::viewer::ViewLighting led_lighting() {
  ls::viewer::ViewLighting lighting;
  for (int l = 0; l < kLeds; ++l) {
    for (int c = 0; c < 3; ++c) lighting.led_irradiance_rgb.push_back(0.01f * (1 + l % 7 + c));
  }
  return lighting;
}

// `count` distant lights spread over the sphere (Fibonacci), as an environment at
// directions_width^2 / 2 texels gives.
ls::viewer::ViewLighting distant_lights(int count) {
  ls::viewer::ViewLighting lighting;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < count; ++k) {
    const double y = 1.0 - 2.0 * (k + 0.5) / count, r = std::sqrt(1.0 - y * y);
    lighting.lights.dirs_in_stage.emplace_back(float(r * std::cos(golden * k)), float(y),
                                               float(r * std::sin(golden * k)));
    lighting.lights.irradiance_rgb.emplace_back(0.02f, 0.015f, 0.01f);
  }
  return lighting;
}

// Lambert + Torrance-Sparrow on every pixel (the most expensive common model).
ls::relight::ModelMaps model_maps() {
  ls::relight::ModelMaps maps;
  maps.maps = ls::Image(kSize, kSize, ls::relight::kMapChannelCount);
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      const Eigen::Vector3d n = normal_at(x, y);
      const float values[] = {float(n.x()), float(n.y()), float(n.z()), 0.5f, 0.4f, 0.3f, 0.0f,
                              0.3f,         0.2f,         3.0f,         1.0f, 1.0f, 0.0f};
      for (int c = 0; c <= ls::relight::kMapFlags; ++c) maps.maps.at(x, y, c) = values[c];
    }
  }
  return maps;
}

void run_frames(benchmark::State& state, ls::viewer::GpuSource& source,
                const ls::viewer::ViewLighting& lighting) {
  ls::viewer::GpuTarget target(source.width(), source.height());
  source.render(lighting, target);  // Warm-up: shader compile on first draw.
  glFinish();
  for (auto _ : state) {
    source.render(lighting, target);
    glFinish();
  }
  state.SetLabel(source.note());
  state.counters["fps"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_FieldFrame(benchmark::State& state) {
  window();
  const auto precision =
      state.range(0) ? ls::viewer::FieldPrecision::kHalf : ls::viewer::FieldPrecision::kFloat;
  const auto source = ls::viewer::upload_field(field(), std::size_t(4) << 30, precision);
  run_frames(state, *source, led_lighting());
}
BENCHMARK(BM_FieldFrame)
    ->ArgName("half")
    ->Arg(1)
    ->Arg(0)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// What the viewer uses on a software renderer (viewer/cpu_sources.h): CPU relighting + upload.
void BM_FieldFrameOnCpu(benchmark::State& state) {
  window();
  const auto source = ls::viewer::relight_field_on_cpu(field());
  run_frames(state, *source, led_lighting());
}
BENCHMARK(BM_FieldFrameOnCpu)->Unit(benchmark::kMillisecond)->UseRealTime();

// sky_sun.exr from the checkout's data folder (LIGHTSTAGE_DATA overrides, as for the viewer).
const ls::physics::EnvironmentMap& sky_sun() {
  static const ls::physics::EnvironmentMap map = [] {
    const char* data = std::getenv("LIGHTSTAGE_DATA");
    const std::filesystem::path dir =
        data ? std::filesystem::path(data)
             : std::filesystem::path(__FILE__).parent_path().parent_path() / "data";
    return ls::physics::EnvironmentMap::load(dir / "envmaps" / "sky_sun.exr");
  }();
  return map;
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// The lighting the viewer makes for the field alone under sky_sun.exr turned by rotation_deg
// (viewer/view_lighting.h), the sun split off or not.
ls::viewer::ViewLighting sky_sun_lighting(double rotation_deg, bool split) {
  ls::viewer::EnvironmentNeeds needs;
  needs.field_sources = split;
  needs.whole_map_led_weights = false;  // Only the field is shown.
  needs.model_lights = false;
  return ls::viewer::environment_lighting(sky_sun(), rotation_deg, field().lights(), needs);
}

std::string sources_label(const ls::viewer::ViewLighting& lighting) {
  return lighting.split ? lighting.split->report() : "by LED cells alone";
}

// A frame of the viewer turning the map (a drag), 0.1 deg a frame: the lighting for the new
// rotation (the sun split off when split = 1), the CPU relighting by cells, the sun added, the
// upload. The first frame with a sun (normals, the sun's LED shadows and flows) is made before the
// timed loop; a new LED triangle every ~100 frames (LEDs ~14 deg apart) is part of the loop.
// Measured on 2 cores (llvmpipe, quiet machine): 21 fps with the sun split off (lighting 5.5 ms,
// the sun ~15 ms, the cells ~26 ms: the 472 MB field streamed once), 33 fps by cells alone.
void BM_FieldSunRotationOnCpu(benchmark::State& state) {
  window();
  const bool split = state.range(0) != 0;
  const auto source = ls::viewer::relight_field_on_cpu(field());
  ls::viewer::GpuTarget target(source->width(), source->height());
  double rotation = 300.0;
  source->render(sky_sun_lighting(rotation, split), target);
  glFinish();
  double lighting_ms = 0;
  for (auto _ : state) {
    rotation += 0.1;
    const auto t0 = std::chrono::steady_clock::now();
    const ls::viewer::ViewLighting lighting = sky_sun_lighting(rotation, split);
    lighting_ms += ms_since(t0);
    source->render(lighting, target);
    glFinish();
  }
  state.SetLabel(sources_label(sky_sun_lighting(rotation, split)));
  state.counters["fps"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["lighting_ms"] =
      benchmark::Counter(lighting_ms / std::max<double>(1, double(state.iterations())));
}
BENCHMARK(BM_FieldSunRotationOnCpu)
    ->ArgName("split")
    ->Arg(1)
    ->Arg(0)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The sun's shadows cast by the scene's shape, as `lightstage relight` casts them: the shape
// recovered on its own thread (recovery_s, the frames meanwhile by the flows), then a frame of a
// sun that stays (its traced visibility kept: the timed loop) and what tracing a new direction
// takes (trace_ms, on its own thread; the frames meanwhile by the flows).
void BM_FieldSunShapeOnCpu(benchmark::State& state) {
  window();
  const auto source = ls::viewer::relight_field_on_cpu(field());
  ls::viewer::GpuTarget target(source->width(), source->height());
  const auto frames_until_the_shape = [&](const ls::viewer::ViewLighting& lighting) {
    const auto t0 = std::chrono::steady_clock::now();
    do {
      source->render(lighting, target);
      glFinish();
    } while (source->shadows().find("the scene's shape where") == std::string::npos &&
             ms_since(t0) < 30 * 60e3);
    return ms_since(t0);
  };
  const double recovery_ms = frames_until_the_shape(sky_sun_lighting(300.0, /*split=*/true));
  const double trace_ms = frames_until_the_shape(sky_sun_lighting(300.5, /*split=*/true));
  const ls::viewer::ViewLighting lighting = sky_sun_lighting(300.5, /*split=*/true);
  for (auto _ : state) {
    source->render(lighting, target);
    glFinish();
  }
  state.SetLabel(source->shadows());
  state.counters["fps"] =
      benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["recovery_s"] = recovery_ms / 1e3;
  state.counters["trace_ms"] = trace_ms;
}
BENCHMARK(BM_FieldSunShapeOnCpu)->Unit(benchmark::kMillisecond)->UseRealTime();

// The first frame with a sun on a freshly opened field: the field's normals (photometric stereo,
// once per field), the shadows of the sun's three LEDs and the flows between them, then the frame.
void BM_FieldSunFirstFrameOnCpu(benchmark::State& state) {
  window();
  const ls::viewer::ViewLighting lighting = sky_sun_lighting(300.0, /*split=*/true);
  ls::viewer::GpuTarget target(field().width(), field().height());
  for (auto _ : state) {
    const auto source = ls::viewer::relight_field_on_cpu(field());
    source->render(lighting, target);
    glFinish();
  }
  state.SetLabel(sources_label(lighting));
}
BENCHMARK(BM_FieldSunFirstFrameOnCpu)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);

// A frame whose sun has jumped 47 deg to LEDs not used before (normals known): the new LEDs'
// shadows and flows, then the frame.
void BM_FieldSunNewLedsOnCpu(benchmark::State& state) {
  window();
  const auto source = ls::viewer::relight_field_on_cpu(field());
  ls::viewer::GpuTarget target(source->width(), source->height());
  double rotation = 300.0;
  source->render(sky_sun_lighting(rotation, /*split=*/true), target);
  glFinish();
  for (auto _ : state) {
    state.PauseTiming();
    rotation += 47.0;  // 7 jumps before the sun comes back near where it was.
    const ls::viewer::ViewLighting lighting = sky_sun_lighting(rotation, /*split=*/true);
    state.ResumeTiming();
    source->render(lighting, target);
    glFinish();
  }
}
BENCHMARK(BM_FieldSunNewLedsOnCpu)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(6);

const ls::relight::PcaField& pca16() {
  static const ls::relight::PcaField pca = [] {
    ls::relight::PcaOptions options;
    options.rank = 16;
    return ls::relight::PcaField::build(field(), options);
  }();
  return pca;
}

void BM_PcaFrame(benchmark::State& state) {
  window();
  const auto source = ls::viewer::upload_pca(pca16());
  run_frames(state, *source, led_lighting());
}
BENCHMARK(BM_PcaFrame)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PcaFrameOnCpu(benchmark::State& state) {
  window();
  const auto source = ls::viewer::relight_pca_on_cpu(pca16());
  run_frames(state, *source, led_lighting());
}
BENCHMARK(BM_PcaFrameOnCpu)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ModelsFrame(benchmark::State& state) {
  window();
  static const ls::relight::ModelMaps maps = model_maps();
  const auto source = ls::viewer::upload_models(maps, {}, ls::viewer::ModelShading::kExact);
  run_frames(state, *source, distant_lights(int(state.range(0))));
}
BENCHMARK(BM_ModelsFrame)
    ->ArgName("lights")
    ->Arg(512)
    ->Arg(2048)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The same maps and lights through the prefiltered environment (ModelShading::kPrefiltered): one
// pass with no per-light work. The lighting does not change between frames, so this is the frame
// alone; BM_ModelsPrefilterRebuild is what a new rotation adds once.
void BM_ModelsPrefilteredFrame(benchmark::State& state) {
  window();
  static const ls::relight::ModelMaps maps = model_maps();
  const auto source = ls::viewer::upload_models(maps, {}, ls::viewer::ModelShading::kPrefiltered);
  run_frames(state, *source, distant_lights(int(state.range(0))));
}
BENCHMARK(BM_ModelsPrefilteredFrame)
    ->ArgName("lights")
    ->Arg(512)
    ->Arg(2048)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// A frame whose lights changed (a new rotation each frame): the CPU prefiltering (SH9 and the
// 8-level stack), its upload and the draw.
void BM_ModelsPrefilterRebuild(benchmark::State& state) {
  window();
  static const ls::relight::ModelMaps maps = model_maps();
  const auto source = ls::viewer::upload_models(maps, {}, ls::viewer::ModelShading::kPrefiltered);
  ls::viewer::ViewLighting lighting = distant_lights(int(state.range(0)));
  ls::viewer::GpuTarget target(source->width(), source->height());
  source->render(lighting, target);
  glFinish();
  float scale = 1.0f;
  for (auto _ : state) {
    scale = scale > 1.5f ? 1.0f : scale * 1.01f;  // Different lights: the cache misses.
    for (Eigen::Vector3f& e : lighting.lights.irradiance_rgb) e.x() = 0.02f * scale;
    source->render(lighting, target);
    glFinish();
  }
  state.SetLabel(source->note());
}
BENCHMARK(BM_ModelsPrefilterRebuild)
    ->ArgName("lights")
    ->Arg(512)
    ->Arg(2048)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_UploadField(benchmark::State& state) {
  window();
  for (auto _ : state) {
    const auto source =
        ls::viewer::upload_field(field(), std::size_t(4) << 30, ls::viewer::FieldPrecision::kHalf);
    glFinish();
  }
}
BENCHMARK(BM_UploadField)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);

}  // namespace

BENCHMARK_MAIN();
