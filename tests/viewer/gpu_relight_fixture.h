#pragma once
// The GPU relighting tests' fixture: one hidden window and a simulated field for the suite, the
// lighting it is viewed under, synthetic model maps, and the difference of a GPU image from the
// CPU's.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include "capture/field.h"
#include "physics/envmap.h"
#include "relight/fit/fit.h"
#include "relight/lighting/light_cells.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"
#include "tests/support/test_support.h"
#include "viewer/gl_window.h"
#include "viewer/gpu_relight.h"

namespace ls::viewer::gpu_testing {

struct ImageDifference {
  double max_relative = 0;   // max |gpu - cpu| / the CPU image's largest value.
  double mean_relative = 0;  // mean |gpu - cpu| / |cpu| over values above 1% of the largest.
  double flux_ratio = 0;     // sum(gpu) / sum(cpu): 1 unless the lighting is mis-scaled.
};

inline ImageDifference difference(const Image& gpu, const Image& cpu) {
  EXPECT_EQ(gpu.width, cpu.width);
  EXPECT_EQ(gpu.height, cpu.height);
  EXPECT_EQ(gpu.channels, 3);
  double peak = 0;
  for (float v : cpu.pixels) peak = std::max(peak, double(std::abs(v)));
  ImageDifference out;
  double sum = 0, gpu_sum = 0, cpu_sum = 0;
  long count = 0;
  for (std::size_t i = 0; i < cpu.pixels.size() && i < gpu.pixels.size(); ++i) {
    gpu_sum += gpu.pixels[i];
    cpu_sum += cpu.pixels[i];
    const double d = std::abs(double(gpu.pixels[i]) - cpu.pixels[i]);
    EXPECT_TRUE(std::isfinite(gpu.pixels[i])) << "value " << i;
    out.max_relative = std::max(out.max_relative, d / std::max(peak, 1e-30));
    if (std::abs(cpu.pixels[i]) > 0.01 * peak) {
      sum += d / std::abs(cpu.pixels[i]);
      ++count;
    }
  }
  out.mean_relative = count > 0 ? sum / count : 0;
  out.flux_ratio = gpu_sum / std::max(cpu_sum, 1e-30);
  EXPECT_GT(peak, 0) << "the CPU image is black: nothing is compared";
  EXPECT_GT(count, long(cpu.pixels.size() / 10)) << "too few lit values to compare";
  return out;
}

inline physics::EnvironmentMap shipped_map(const std::string& name) {
  return physics::EnvironmentMap::load(testing::source_dir() / "data" / "envmaps" /
                                       (name + ".exr"));
}

// One hidden window and a 64 x 48 simulated field of the glossy RTI scene (40 LEDs) for the suite.
class GpuRelight : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    window_ = new GlWindow(64, 64, "gpu_relight_test", false);
    std::cout << "renderer: " << window_->renderer() << "\n";
    Stage stage = sim::rti_dome_stage(40, 10.0, 64);
    stage.camera.height = 48;
    capture::FieldNoise noise;
    noise.read_variance = 1e-5;
    noise.shot_variance_per_unit = 2e-4;
    field_ = new capture::ReflectanceField(
        sim::render_noisy_field(stage, sim::rti_scene(sim::RtiScene::kGlossy), noise, 3));
    for (const capture::FieldLight& light : field_->lights()) {
      led_dirs_.push_back(light.dir_in_stage);
    }
  }
  static void TearDownTestSuite() {
    delete field_;
    delete window_;
    led_dirs_.clear();
  }

  // The environment's per-LED irradiance, rotated.
  static ViewLighting environment(double rotation_deg) {
    ViewLighting lighting;
    const physics::EnvironmentMap map = shipped_map("softbox_studio");
    lighting.led_irradiance_rgb =
        relight::integrate_environment(map, led_dirs_, rotation_deg).irradiance_rgb;
    relight::EnvironmentSampling sampling;
    sampling.directions_width = 32;  // 512 directions.
    lighting.lights = relight::LightingForModels::environment(map, rotation_deg, sampling);
    return lighting;
  }
  // A point light between LEDs: LED weights through the RBF interpolation (a few LEDs lit).
  static ViewLighting point_light() {
    ViewLighting lighting;
    lighting.lights = relight::LightingForModels::directional(Eigen::Vector3d(0.4, 0.5, 0.8),
                                                              Eigen::Vector3d(2.0, 1.5, 1.0));
    const relight::LightInterpolator interpolator(field_->lights());
    lighting.led_irradiance_rgb = interpolator.led_irradiance(lighting.lights);
    return lighting;
  }

  static Image gpu_render(GpuSource& source, const ViewLighting& lighting) {
    GpuTarget target(source.width(), source.height());
    source.render(lighting, target);
    return target.read_back();
  }

  inline static GlWindow* window_ = nullptr;
  inline static capture::ReflectanceField* field_ = nullptr;
  inline static std::vector<Eigen::Vector3d> led_dirs_;
};

// Model maps with every model, random normals over the upper hemisphere, parameters over their
// valid ranges, and flagged pixels; some normals face away and some lobes are very sharp (Phong up
// to 1e4, Beckmann m down to 0.02), and some k_s above the render clamp.
inline relight::ModelMaps synthetic_maps(int width, int height, uint64_t seed) {
  relight::ModelMaps maps;
  maps.maps = Image(width, height, relight::kMapChannelCount);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const int model = (x + 2 * y) % 5;  // 0 = flagged.
      Eigen::Vector3d n(u(rng) * 2 - 1, u(rng) * 2 - 1, u(rng) * 1.2 - 0.2);
      if (n.norm() < 1e-3) n = Eigen::Vector3d(0, 0, 1);
      n.normalize();
      const double roughness = 0.02 + 0.98 * std::pow(u(rng), 2);
      const float values[] = {float(n.x()),
                              float(n.y()),
                              float(n.z()),
                              float(u(rng)),
                              float(u(rng)),
                              float(u(rng)),
                              model == 2 ? float(u(rng) * 1.5) : 0.0f,
                              model >= 3 ? float(u(rng) * 2.5) : 0.0f,
                              model >= 3 ? float(roughness) : 0.2f,
                              float(model),
                              1.0f,
                              1.0f,
                              model == 0 ? float(relight::kFitFailed) : 0.0f};
      for (int c = 0; c <= relight::kMapFlags; ++c) maps.maps.at(x, y, c) = values[c];
    }
  }
  maps.maps.channel_names = relight::model_map_channel_names();
  return maps;
}

}  // namespace ls::viewer::gpu_testing
