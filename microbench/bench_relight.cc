// Relighting throughput (GB/s of field streamed, against a memcpy of as many bytes measured in the
// same run): a field in memory, and a half-float file's rows as relight's bands sum them;
// environment integration and light-cell computation for the default dome.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include "capture/exr_band_reader.h"
#include "capture/field.h"
#include "lightstage/stage.h"
#include "physics/envmap.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"

namespace {

const std::vector<Eigen::Vector3d>& dome() {
  static const std::vector<Eigen::Vector3d> dirs = ls::default_stage().led_directions();
  return dirs;
}

// One field per size, built once: filling ~470 MB is slower than relighting it.
const ls::capture::ReflectanceField& field(int size) {
  static std::map<int, std::unique_ptr<ls::capture::ReflectanceField>> fields;
  auto& slot = fields[size];
  if (!slot) {
    std::vector<ls::capture::FieldLight> lights(dome().size());
    slot = std::make_unique<ls::capture::ReflectanceField>(size, size, lights);
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> value(0.0f, 1.0f);
    float* p = slot->pixel(0, 0);
    for (size_t i = 0; i < slot->values().size(); ++i) p[i] = value(rng);
  }
  return *slot;
}

int threads_for(int arg) { return arg > 0 ? arg : int(tbb::info::default_concurrency()); }

// Seconds per memcpy of `bytes` (the best of a few), for the ratio counter.
double memcpy_seconds(size_t bytes, int threads) {
  static std::map<std::pair<size_t, int>, double> cache;
  auto it = cache.find({bytes, threads});
  if (it != cache.end()) return it->second;
  std::vector<char> src(bytes, 1), dst(bytes, 0);
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  double best = 1e30;
  for (int rep = 0; rep < 5; ++rep) {
    const auto start = std::chrono::steady_clock::now();
    // Chunks copied in parallel, like relight's row tiles.
    const size_t chunk = 1 << 20;
    tbb::parallel_for(size_t(0), (bytes + chunk - 1) / chunk, [&](size_t k) {
      const size_t begin = k * chunk, n = std::min(chunk, bytes - begin);
      std::memcpy(dst.data() + begin, src.data() + begin, n);
    });
    benchmark::DoNotOptimize(dst.data());
    best = std::min(
        best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return cache[{bytes, threads}] = best;
}

// Runs `relight` (streaming `bytes`) on `threads` over the state's iterations: its throughput, and
// against a memcpy of as many bytes (1.0 = as fast as memcpy; memcpy also writes what it reads, so
// a read-only stream can exceed 1).
template <typename Relight>
void time_against_memcpy(benchmark::State& state, std::size_t bytes, int threads,
                         const Relight& relight) {
  const double copy_s = memcpy_seconds(bytes, threads);
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  const auto start = std::chrono::steady_clock::now();
  for (auto _ : state) relight();
  const double relight_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() /
      double(state.iterations());
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(bytes));
  state.counters["threads"] = threads;
  state.counters["memcpy_GBps"] = double(bytes) / copy_s / 1e9;
  state.counters["vs_memcpy"] = copy_s / relight_s;
}

// Args: field size (pixels per side), threads (0 = all).
void BM_Relight(benchmark::State& state) {
  const int threads = threads_for(int(state.range(1)));
  const auto& f = field(int(state.range(0)));
  std::vector<float> e(3 * f.num_lights(), 0.01f);
  ls::Image out;
  time_against_memcpy(state, f.bytes(), threads, [&] {
    ls::relight::relight_into(f, e, out);
    benchmark::DoNotOptimize(out.pixels.data());
  });
  state.counters["field_MB"] = f.bytes() / 1e6;
}
BENCHMARK(BM_Relight)
    ->Args({512, 1})
    ->Args({512, 0})
    ->Args({128, 1})
    ->Args({128, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(0.2);

// A half-float field's rows as a file holds them (one plane per channel a row), in memory: the
// sums relight's bands make of them (relight_rows_into, halves converted as they are summed).
// Args: field size (pixels per side), threads (0 = all).
void BM_RelightHalfRows(benchmark::State& state) {
  const int size = int(state.range(0)), threads = threads_for(int(state.range(1)));
  const int count = 3 * int(dome().size());
  const size_t row_bytes = size_t(size) * size_t(count) * 2;
  std::vector<char> halves(row_bytes * size_t(size));
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> half(0x2000, 0x3bff);  // Finite, in (0, 1).
  for (size_t i = 0; i + 1 < halves.size(); i += 2) {
    const auto h = static_cast<std::uint16_t>(half(rng));
    std::memcpy(&halves[i], &h, 2);
  }
  std::vector<int> to_pixel_index(size_t(count), 0);
  for (int i = 0; i < count; ++i) to_pixel_index[size_t(i)] = i;
  ls::capture::PlanarRows rows{nullptr, 0, size, size, to_pixel_index, halves.data(), row_bytes};
  std::vector<float> e(size_t(count), 0.01f);
  ls::Image out(size, size, 3);
  time_against_memcpy(state, halves.size(), threads, [&] {
    ls::relight::relight_rows_into(rows, e, out);
    benchmark::DoNotOptimize(out.pixels.data());
  });
}
BENCHMARK(BM_RelightHalfRows)
    ->Args({1024, 1})
    ->Args({1024, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(0.5);

// Arg: map width (height = width / 2); the dome's 151 LEDs, a new rotation each iteration.
void BM_IntegrateEnvironment(benchmark::State& state) {
  const int width = int(state.range(0));
  ls::Image image(width, width / 2, 3, 1.0f);
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> value(0.0f, 5.0f);
  for (float& v : image.pixels) v = value(rng);
  const ls::physics::EnvironmentMap map(image);
  double rotation_deg = 0;
  for (auto _ : state) {
    auto weights = ls::relight::integrate_environment(map, dome(), rotation_deg);
    benchmark::DoNotOptimize(weights.irradiance_rgb.data());
    rotation_deg += 1.0;
  }
  state.counters["leds"] = double(dome().size());
}
BENCHMARK(BM_IntegrateEnvironment)
    ->Arg(512)
    ->Arg(1024)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(0.2);

// Arg: resolution (width of the lat-long quadrature grid), supersample 2.
void BM_LightCellsCompute(benchmark::State& state) {
  for (auto _ : state) {
    auto cells = ls::relight::LightCells::compute(dome(), 0.0, int(state.range(0)));
    benchmark::DoNotOptimize(cells.solid_angle_sr.data());
  }
  state.counters["leds"] = double(dome().size());
}
BENCHMARK(BM_LightCellsCompute)
    ->Arg(1024)
    ->Arg(2048)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(0.2);

}  // namespace

BENCHMARK_MAIN();
