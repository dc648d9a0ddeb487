// Relight time per frame of each compact representation at 512 x 512 pixels x 150 LEDs against the
// raw field, lit by an environment map given as per-LED irradiance (integrate_environment): the
// raw field streams 1.8 KB per pixel, PCA k x 3 floats, PTM/HSH their 6..16 terms per channel.
// Also the PCA build (Gram matrix + eigen-decomposition + coefficients) at that size, the OpenLIME
// planes' build, and their basis's eigenvectors.
#include <benchmark/benchmark.h>

#include <Eigen/Dense>
#include <cmath>
#include <map>
#include <memory>

#include "capture/field.h"
#include "relight/compact/leading_eigenvectors.h"
#include "relight/compact/pca_field.h"
#include "relight/compact/plane_field.h"
#include "relight/compact/rti_fits.h"
#include "relight/lighting/relight.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"

namespace {

constexpr int kSize = 512;

const ls::Stage& dome() {
  static const ls::Stage stage = ls::sim::rti_dome_stage(150, 10.0, kSize);
  return stage;
}

// A smooth field of modest rank plus noise (what relighting costs does not depend on the values;
// the PCA build's eigen-decomposition does not either).
const ls::capture::ReflectanceField& field() {
  static std::unique_ptr<ls::capture::ReflectanceField> f;
  if (!f) {
    std::vector<ls::capture::FieldLight> lights;
    for (const auto& led : dome().leds) lights.push_back({led.id, led.dir_in_stage, true});
    f = std::make_unique<ls::capture::ReflectanceField>(kSize, kSize, lights);
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        const Eigen::Vector3d n =
            Eigen::Vector3d(std::sin(x * 0.01), std::cos(y * 0.013), 1.5).normalized();
        float* p = f->pixel(x, y);
        for (size_t l = 0; l < lights.size(); ++l) {
          const float shade = float(std::max(0.0, n.dot(lights[l].dir_in_stage)));
          for (int c = 0; c < 3; ++c) p[3 * l + c] = shade * (0.3f + 0.2f * c);
        }
      }
    }
    ls::capture::FieldNoise noise;  // Read noise only, sigma 0.002.
    noise.read_variance = 4e-6;
    ls::sim::add_sensor_noise(*f, noise, /*seed=*/1);
  }
  return *f;
}

const ls::relight::LightingForModels& env_lights() {
  static const ls::relight::LightingForModels lights = [] {
    ls::relight::LightingForModels l;
    const auto dirs = dome().led_directions();
    for (size_t i = 0; i < dirs.size(); ++i) {
      l.dirs_in_stage.push_back(dirs[i].cast<float>());
      l.irradiance_rgb.push_back(Eigen::Vector3f(0.01f * (i % 7), 0.02f, 0.015f));
    }
    return l;
  }();
  return lights;
}

std::vector<float> led_weights() {
  std::vector<float> w;
  for (const auto& e : env_lights().irradiance_rgb) w.insert(w.end(), {e[0], e[1], e[2]});
  return w;
}

void BM_RawField(benchmark::State& state) {
  const auto& f = field();
  const std::vector<float> w = led_weights();
  ls::Image out;
  for (auto _ : state) ls::relight::relight_into(f, w, out);
  state.counters["bytes_per_pixel"] = 12.0 * f.num_lights();
}
BENCHMARK(BM_RawField)->Unit(benchmark::kMillisecond)->UseRealTime();

const ls::relight::PcaField& pca(int rank, int tile) {
  static std::map<std::pair<int, int>, std::unique_ptr<ls::relight::PcaField>> cache;
  auto& slot = cache[{rank, tile}];
  if (!slot) {
    ls::relight::PcaOptions options;
    options.rank = rank;
    options.tile_size = tile;
    slot = std::make_unique<ls::relight::PcaField>(ls::relight::PcaField::build(field(), options));
  }
  return *slot;
}

// Projection of the LED weights onto the basis (per tile) + a k-term sum per pixel.
void BM_Pca(benchmark::State& state) {
  const auto& p = pca(int(state.range(0)), int(state.range(1)));
  const std::vector<float> w = led_weights();
  ls::Image out;
  for (auto _ : state) p.relight_led_weights_into(w.data(), out);
  state.counters["bytes_per_pixel"] = p.bytes_per_pixel();
}
BENCHMARK(BM_Pca)
    ->ArgsProduct({{4, 8, 16, 32}, {0, 64}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The same through the generic interface: 150 lights turned into LED weights by the RBF first.
void BM_PcaGenericLights(benchmark::State& state) {
  const auto& p = pca(16, 0);
  ls::Image out;
  for (auto _ : state) p.relight_into(env_lights(), out);
}
BENCHMARK(BM_PcaGenericLights)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Rti(benchmark::State& state) {
  static std::map<int, std::unique_ptr<ls::relight::RtiField>> cache;
  auto& slot = cache[int(state.range(0))];
  if (!slot) {
    ls::relight::RtiFitOptions options;
    options.basis = ls::relight::RtiBasis(state.range(0) % 10);
    options.lrgb = state.range(0) >= 10;
    slot = std::make_unique<ls::relight::RtiField>(ls::relight::RtiField::fit(field(), options));
  }
  ls::Image out;
  for (auto _ : state) slot->relight_into(env_lights(), out);
  state.SetLabel(slot->name());
  state.counters["bytes_per_pixel"] = slot->bytes_per_pixel();
}
// 0 ptm-rgb, 10 ptm-lrgb, 1..3 hsh2..4.
BENCHMARK(BM_Rti)
    ->Arg(0)
    ->Arg(10)
    ->Arg(1)
    ->Arg(2)
    ->Arg(3)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_PcaBuild(benchmark::State& state) {
  ls::relight::PcaOptions options;
  options.rank = 16;
  options.tile_size = int(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(ls::relight::PcaField::build(field(), options));
}
BENCHMARK(BM_PcaBuild)
    ->Arg(0)
    ->Arg(64)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(2);

void BM_RtiFit(benchmark::State& state) {
  ls::relight::RtiFitOptions options;
  options.basis = ls::relight::RtiBasis::kHsh3;
  for (auto _ : state) benchmark::DoNotOptimize(ls::relight::RtiField::fit(field(), options));
}
BENCHMARK(BM_RtiFit)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);

// OpenLIME planes as `export openlime` makes them at 512^2 x 150 LEDs: sigma (rbf, 0) or the grid
// (bilinear, 1) and the planes chosen on held-out lights, then the basis and the codes.
void BM_PlaneFieldBuild(benchmark::State& state) {
  ls::relight::PlaneFieldOptions options;
  options.interpolation = state.range(0) == 0 ? ls::relight::PlaneInterpolation::kRbf
                                              : ls::relight::PlaneInterpolation::kBilinear;
  for (auto _ : state) benchmark::DoNotOptimize(ls::relight::PlaneField::build(field(), options));
}
BENCHMARK(BM_PlaneFieldBuild)
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(2);

// A PCA basis of 30 planes out of 720 dimensions (240 lights x 3 channels): every eigenvector by
// Eigen's solver (0) against the 30 leading ones alone (1).
void BM_PlaneBasisEigenvectors(benchmark::State& state) {
  const int n = 720;
  Eigen::VectorXd values(n);
  for (int i = 0; i < n; ++i) values(i) = std::pow(0.9, i);
  std::srand(3);
  const Eigen::MatrixXd q =
      Eigen::HouseholderQR<Eigen::MatrixXd>(Eigen::MatrixXd::Random(n, n)).householderQ();
  const Eigen::MatrixXd covariance = q * values.asDiagonal() * q.transpose();
  for (auto _ : state) {
    if (state.range(0) == 0) {
      benchmark::DoNotOptimize(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(covariance));
    } else {
      benchmark::DoNotOptimize(ls::relight::leading_eigenvectors(covariance, 30));
    }
  }
}
BENCHMARK(BM_PlaneBasisEigenvectors)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
