// GPU relighting (viewer/gpu_relight.h) against the CPU for the same inputs: the field, its PCA
// and fitted-model maps, under an environment map and a point light, read back from the
// framebuffer. Runs on llvmpipe under Xvfb (tests/viewer/with_xvfb.sh starts one per binary).
#include "viewer/gpu_relight.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <optional>
#include <random>
#include <string>

#include "lightstage/errors.h"
#include "physics/envmap.h"
#include "relight/compact/pca_field.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "relight/lighting/half_relight.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"
#include "tests/support/test_support.h"
#include "viewer/cpu_sources.h"
#include "viewer/gl_window.h"

namespace ls::viewer {
namespace {

struct ImageDifference {
  double max_relative = 0;   // max |gpu - cpu| / the CPU image's largest value.
  double mean_relative = 0;  // mean |gpu - cpu| / |cpu| over values above 1% of the largest.
  double flux_ratio = 0;     // sum(gpu) / sum(cpu): 1 unless the lighting is mis-scaled.
};

ImageDifference difference(const Image& gpu, const Image& cpu) {
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

physics::EnvironmentMap shipped_map(const std::string& name) {
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
    const relight::LightInterpolator interpolator(led_dirs_, {});
    lighting.led_irradiance_rgb = interpolator.led_irradiance(lighting.lights);
    return lighting;
  }

  static Image gpu_render(GpuSource& source, const ViewLighting& lighting) {
    GpuTarget target(source.width(), source.height());
    source.render(lighting, target);
    return target.read_back();
  }

  static GlWindow* window_;
  static capture::ReflectanceField* field_;
  static std::vector<Eigen::Vector3d> led_dirs_;
};
GlWindow* GpuRelight::window_ = nullptr;
capture::ReflectanceField* GpuRelight::field_ = nullptr;
std::vector<Eigen::Vector3d> GpuRelight::led_dirs_;

Image cpu_field(const capture::ReflectanceField& field, const ViewLighting& lighting) {
  Image out;
  relight::relight_into(field, lighting.led_irradiance_rgb, out);
  return out;
}

TEST_F(GpuRelight, FieldInFloatAndHalfMatchesTheCpu) {
  for (const FieldPrecision precision : {FieldPrecision::kFloat, FieldPrecision::kHalf}) {
    const auto source = upload_field(*field_, std::size_t(1) << 30, precision);
    std::cout << source->note() << "\n";
    EXPECT_EQ(source->name(), "field");
    EXPECT_NE(source->note().find(precision == FieldPrecision::kHalf ? "half" : "float"),
              std::string::npos);
    for (const ViewLighting& lighting : {environment(0), environment(137), point_light()}) {
      const ImageDifference d =
          difference(gpu_render(*source, lighting), cpu_field(*field_, lighting));
      std::cout << "field " << (precision == FieldPrecision::kHalf ? "half" : "float") << ": max "
                << d.max_relative << ", mean " << d.mean_relative << "\n";
      if (precision == FieldPrecision::kFloat) {
        // Only the summation order differs. Measured max 1.6e-7, mean 7.7e-8.
        EXPECT_LT(d.max_relative, 1e-5);
        EXPECT_LT(d.mean_relative, 1e-5);
      } else {
        // Half keeps 11 bits: 2.4e-4 relative per value at most. Measured max 2.8e-4 (of the
        // peak), mean 1.8e-4.
        EXPECT_LT(d.max_relative, 1e-3);
        EXPECT_LT(d.mean_relative, 5e-4);
      }
    }
  }
}

TEST_F(GpuRelight, AutomaticPrecisionMeasuresHalfAndPrefersFloatOnLlvmpipe) {
  const auto source = upload_field(*field_);
  std::cout << source->note() << "\n";
  // Half keeps the sampled relit error under 1e-3 (measured 2.2e-4), so it would be chosen, but
  // on a software renderer (these tests run on llvmpipe) float is faster and fits the budget.
  EXPECT_NE(source->note().find("<= 1e-3"), std::string::npos) << source->note();
  const bool software = window_->renderer().find("llvmpipe") != std::string::npos;
  EXPECT_EQ(source->bytes(), std::size_t(64) * 48 * 40 * 3 * (software ? 4 : 2)) << source->note();
}

TEST_F(GpuRelight, PcaMatchesTheCpuGlobalAndTiled) {
  for (const int tile_size : {0, 16}) {
    relight::PcaOptions options;
    options.rank = 12;
    options.tile_size = tile_size;
    const relight::PcaField pca = relight::PcaField::build(*field_, options);
    const auto source = upload_pca(pca);
    std::cout << source->note() << "\n";
    EXPECT_EQ(source->name(), "pca k=12");
    for (const ViewLighting& lighting : {environment(45), point_light()}) {
      Image cpu;
      pca.relight_led_weights_into(lighting.led_irradiance_rgb.data(), cpu);
      const ImageDifference d = difference(gpu_render(*source, lighting), cpu);
      std::cout << "pca tile " << tile_size << ": max " << d.max_relative << ", mean "
                << d.mean_relative << "\n";
      // Float both sides, k = 12 terms. Measured 0 on llvmpipe (same summation order).
      EXPECT_LT(d.max_relative, 1e-5);
      EXPECT_LT(d.mean_relative, 1e-5);
    }
  }
}

// The software-renderer path (viewer/cpu_sources.h): the CPU result, uploaded and read back
// through the same target, row order included.
TEST_F(GpuRelight, CpuSourcesUploadTheCpuRelightingExactly) {
  EXPECT_EQ(software_renderer(), window_->renderer().find("llvmpipe") != std::string::npos);
  relight::PcaOptions options;
  options.rank = 12;
  const relight::PcaField pca = relight::PcaField::build(*field_, options);
  const auto field_source = relight_field_on_cpu(*field_);
  const auto pca_source = relight_pca_on_cpu(pca);
  EXPECT_NE(field_source->note().find("CPU"), std::string::npos);
  // The field is streamed in half floats where their relit error allows (HalfField): the upload
  // is that relighting exactly, and within half's 1e-3 of the float one.
  const std::optional<relight::HalfField> half = relight::HalfField::of(*field_);
  for (const ViewLighting& lighting : {environment(137), point_light()}) {
    const Image uploaded = gpu_render(*field_source, lighting);
    Image expected = cpu_field(*field_, lighting);
    EXPECT_LT(difference(uploaded, expected).max_relative, 1e-3);
    if (half) half->relight_into(lighting.led_irradiance_rgb, expected);
    EXPECT_EQ(difference(uploaded, expected).max_relative, 0.0);
    Image cpu;
    pca.relight_led_weights_into(lighting.led_irradiance_rgb.data(), cpu);
    EXPECT_EQ(difference(gpu_render(*pca_source, lighting), cpu).max_relative, 0.0);
  }
  ViewLighting wrong = environment(0);
  wrong.led_irradiance_rgb.pop_back();
  GpuTarget target(field_->width(), field_->height());
  EXPECT_THROW(field_source->render(wrong, target), InputError);
}

TEST_F(GpuRelight, FieldOverTheBudgetFallsBackToPcaAndSaysSo) {
  // The field needs 737 kB in half; 300 kB hold 8 ranks of float coefficients (36.9 kB each).
  const auto source = upload_field(*field_, 300000);
  std::cout << source->note() << "\n";
  EXPECT_EQ(source->name(), "pca k=8");
  EXPECT_NE(source->note().find("over the"), std::string::npos) << source->note();
  EXPECT_NE(source->note().find("budget"), std::string::npos) << source->note();
  EXPECT_LE(source->bytes(), 300000u);
  // The same compression on the CPU (noise-floor rank, capped by the budget) relights the same.
  relight::PcaOptions options;
  options.max_rank = 8;
  const relight::PcaField pca = relight::PcaField::build(*field_, options);
  const ViewLighting lighting = environment(90);
  Image cpu;
  pca.relight_led_weights_into(lighting.led_irradiance_rgb.data(), cpu);
  const ImageDifference d = difference(gpu_render(*source, lighting), cpu);
  EXPECT_LT(d.max_relative, 1e-5);  // Measured 0 (same summation order on llvmpipe).
  // Not even rank 1 fits: a HardwareError that says how much was needed.
  try {
    upload_field(*field_, 1000);
    ADD_FAILURE() << "a 1 kB budget was accepted";
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find("over the 1.0 kB"), std::string::npos) << e.what();
  }
}

// Model maps with every model, random normals over the upper hemisphere, parameters over their
// valid ranges, and flagged pixels; some normals face away and some lobes are very sharp (Phong up
// to 1e4, Beckmann m down to 0.02), and some k_s above the render clamp.
relight::ModelMaps synthetic_maps(int width, int height, uint64_t seed) {
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

TEST_F(GpuRelight, ModelsMatchTheCpuUnderAnEnvironmentAndAPointLight) {
  const relight::ModelMaps maps = synthetic_maps(64, 48, 11);
  Image fallback(64, 48, 3, 0.25f);
  for (const bool with_fallback : {false, true}) {
    relight::ModelRenderOptions options;
    options.flagged_fallback = with_fallback ? &fallback : nullptr;
    const auto source = upload_models(maps, options);
    for (const ViewLighting& lighting : {environment(200), point_light()}) {
      const Image gpu = gpu_render(*source, lighting);
      std::cout << source->note() << "\n";
      const Image cpu = relight::render_models(maps, lighting.lights, options);
      const ImageDifference d = difference(gpu, cpu);
      std::cout << "models (" << lighting.lights.dirs_in_stage.size() << " lights): max "
                << d.max_relative << ", mean " << d.mean_relative << "\n";
      // Float both sides; GLSL's exp/pow are less exact than libm's (Phong at n = 1e4 loses most).
      // Measured max 1.9e-5, mean 5.1e-7.
      EXPECT_LT(d.max_relative, 1e-4);
      EXPECT_LT(d.mean_relative, 1e-4);
      // Flagged pixels: black, or the fallback.
      EXPECT_EQ(gpu.at(0, 0, 1), with_fallback ? 0.25f : 0.0f);
    }
  }
}

TEST_F(GpuRelight, ModelsUnderMoreLightsThanOnePassTakes) {
  const relight::ModelMaps maps = synthetic_maps(32, 24, 7);
  ViewLighting lighting;
  relight::EnvironmentSampling sampling;
  sampling.directions_width = 64;  // 2048 directions, fewer where the map is black.
  lighting.lights = relight::LightingForModels::environment(shipped_map("sky_sun"), 10.0, sampling);
  ASSERT_GT(lighting.lights.dirs_in_stage.size(), 1024u);
  Image fallback(32, 24, 3, 0.5f);
  relight::ModelRenderOptions options;
  options.flagged_fallback = &fallback;
  const auto source = upload_models(maps, options);
  const Image gpu = gpu_render(*source, lighting);
  std::cout << source->note() << "\n";
  EXPECT_NE(source->note().find("passes"), std::string::npos) << source->note();
  const ImageDifference d = difference(gpu, relight::render_models(maps, lighting.lights, options));
  std::cout << "models, several passes: max " << d.max_relative << ", mean " << d.mean_relative
            << "\n";
  EXPECT_LT(d.max_relative, 1e-4);  // Measured max 8.7e-6, mean 1.0e-6.
  EXPECT_LT(d.mean_relative, 1e-4);
  EXPECT_EQ(gpu.at(0, 0, 0), 0.5f);  // Flagged: the fallback once, not once per pass.
}

TEST_F(GpuRelight, ModelsWithPerPixelViewDirections) {
  const relight::ModelMaps maps = synthetic_maps(32, 24, 5);
  relight::ModelRenderOptions options;
  for (int y = 0; y < 24; ++y) {
    for (int x = 0; x < 32; ++x) {
      options.view_dir_per_pixel.push_back(Eigen::Vector3d((x - 16) / 40.0, (y - 12) / 40.0, 1));
    }
  }
  const auto source = upload_models(maps, options);
  EXPECT_NE(source->note().find("per-pixel"), std::string::npos);
  const ViewLighting lighting = environment(30);
  const ImageDifference d = difference(gpu_render(*source, lighting),
                                       relight::render_models(maps, lighting.lights, options));
  EXPECT_LT(d.max_relative, 1e-4);  // As above.
}

// Prefiltered shading (ModelShading::kPrefiltered) against the exact CPU render_models under the
// softbox studio map sampled as the viewer does (64 x 32 directions: 2048 lights, fewer where the
// map is black), on maps fitted to the simulated sphere-and-backdrop scenes (64 x 48, 40 LEDs).
// Errors as everywhere in this file: max |gpu - cpu| relative to the CPU image's peak, and the mean
// relative error over values above 1% of the peak (dim values, where SH9 rings, weigh in fully).
class PrefilteredModels : public GpuRelight {
 protected:
  static relight::ModelMaps fitted_maps(sim::RtiScene scene, bool lobes) {
    Stage stage = sim::rti_dome_stage(40, 10.0, 64);
    stage.camera.height = 48;
    capture::FieldNoise noise;
    noise.read_variance = 1e-5;
    noise.shot_variance_per_unit = 2e-4;
    const capture::ReflectanceField field =
        sim::render_noisy_field(stage, sim::rti_scene(scene), noise, 3);
    relight::FitOptions options;
    options.fit_torrance_sparrow = lobes;
    // The bounds below were measured on maps from this solver; they guard the prefiltering, so
    // the maps stay put when the default solver changes (the profiled solver's maps differ on a
    // handful of grazing rim pixels of the 40-LED dome, where one bright lobe sets the maximum).
    options.solver = relight::FitSolver::kEveryCandidateByLm;
    options.materials = relight::FitMaterials::kPerPixel;  // Likewise per-pixel, as measured.
    relight::ModelMaps maps = relight::fit_models(field, options);
    maps.shadows = {};  // Prefiltered shading has no shadows: the exact render without them.
    return maps;
  }
  static ViewLighting studio(double rotation_deg) {
    ViewLighting lighting;
    relight::EnvironmentSampling sampling;
    sampling.directions_width = 64;
    lighting.lights = relight::LightingForModels::environment(shipped_map("softbox_studio"),
                                                              rotation_deg, sampling);
    return lighting;
  }
  // Prefiltered GPU and exact CPU renders at two rotations (the second rebuilds the prefiltering).
  static std::vector<std::pair<Image, Image>> renders(const relight::ModelMaps& maps) {
    const auto source = upload_models(maps, {}, ModelShading::kPrefiltered);
    std::vector<std::pair<Image, Image>> out;
    for (const double rotation : {0.0, 137.0}) {
      const ViewLighting lighting = studio(rotation);
      out.emplace_back(gpu_render(*source, lighting),
                       relight::render_models(maps, lighting.lights));
      std::cout << source->note() << "\n";
      EXPECT_NE(source->note().find("prefiltered"), std::string::npos) << source->note();
    }
    return out;
  }
  static std::vector<ImageDifference> compare(const relight::ModelMaps& maps) {
    std::vector<ImageDifference> out;
    for (const auto& [gpu, cpu] : renders(maps)) out.push_back(difference(gpu, cpu));
    return out;
  }
  // The synthetic maps with every fitted pixel given `model`; lobes k_s 0.5 with m 0.1 .. 0.5 (the
  // range the fits give), Oren-Nayar sigma 0.4.
  static relight::ModelMaps one_model(int model, uint64_t seed) {
    relight::ModelMaps maps = synthetic_maps(64, 48, seed);
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 64; ++x) {
        float* m = &maps.maps.pixels[(std::size_t(y) * 64 + x) * relight::kMapChannelCount];
        if (m[relight::kMapModel] != 0) m[relight::kMapModel] = float(model);
        m[relight::kMapKs] = model >= 3 ? 0.5f : 0.0f;
        m[relight::kMapRoughness] = 0.1f + 0.4f * float((x * 7 + y * 3) % 17) / 16;
        m[relight::kMapSigma] = model == 2 ? 0.4f : 0.0f;
      }
    }
    return maps;
  }
};

// Bounds on the prefiltered render against the exact one: regression guards, the measured value
// (in the comments) plus about 25%. The flux ratio is not a guard: SH9 keeps the irradiance's
// constant and linear terms exactly and the split sum keeps the lobe's energy, so over the whole
// image the prefiltered render carries the exact render's light to within a few percent, and any
// mis-scaled prefiltering (a missing 1 / pi, a factor 2) is far outside.
struct PrefilterBounds {
  double max_relative, mean_relative, flux_ratio_error;
};
constexpr PrefilterBounds kDiffuseBounds{0.107, 0.145, 0.05};
constexpr PrefilterBounds kGlossyBounds{0.166, 0.149, 0.05};

bool within(const ImageDifference& d, const PrefilterBounds& b) {
  return d.max_relative < b.max_relative && d.mean_relative < b.mean_relative &&
         std::abs(d.flux_ratio - 1) < b.flux_ratio_error;
}

TEST_F(PrefilteredModels, DiffuseSceneMatchesTheExactRender) {
  // The matte scene fitted without lobes: Lambert and Oren-Nayar pixels only.
  const relight::ModelMaps maps = fitted_maps(sim::RtiScene::kMatte, false);
  for (const ImageDifference& d : compare(maps)) {
    std::cout << "prefiltered, diffuse scene: max " << d.max_relative << ", mean "
              << d.mean_relative << ", flux ratio " << d.flux_ratio << "\n";
    // SH9 irradiance (its clamped-cosine truncation: a few % of the peak under a few bright
    // softboxes). Measured max 0.071 and 0.085 (rotations 0 and 137 deg), mean 0.069 and 0.115.
    EXPECT_LT(d.max_relative, kDiffuseBounds.max_relative);
    EXPECT_LT(d.mean_relative, kDiffuseBounds.mean_relative);
    EXPECT_NEAR(d.flux_ratio, 1.0, kDiffuseBounds.flux_ratio_error);
  }
}

TEST_F(PrefilteredModels, GlossySceneMatchesTheExactRender) {
  // The glossy scene (Torrance-Sparrow k_s 0.5, m 0.2) fitted with lobes.
  const relight::ModelMaps maps = fitted_maps(sim::RtiScene::kGlossy, true);
  for (const ImageDifference& d : compare(maps)) {
    std::cout << "prefiltered, glossy scene: max " << d.max_relative << ", mean " << d.mean_relative
              << ", flux ratio " << d.flux_ratio << "\n";
    // Split sum: the lobe's shape at oblique views (stretched, clipped by the horizon) is lost.
    // Measured max 0.133 and 0.117 (rotations 0 and 137 deg), mean 0.084 and 0.119.
    EXPECT_LT(d.max_relative, kGlossyBounds.max_relative);
    EXPECT_LT(d.mean_relative, kGlossyBounds.mean_relative);
    EXPECT_NEAR(d.flux_ratio, 1.0, kGlossyBounds.flux_ratio_error);
  }
}

// The bounds above catch a mis-scaled prefiltering: the render is linear in the prefiltered
// environment, so scaling the GPU image is scaling what the prefilter produced. Off by 2, 1/2, pi,
// 1/pi, or even 10%, every comparison falls outside its bounds.
TEST_F(PrefilteredModels, MisScaledPrefilteringWouldFailTheBounds) {
  const std::pair<sim::RtiScene, PrefilterBounds> cases[] = {
      {sim::RtiScene::kMatte, kDiffuseBounds}, {sim::RtiScene::kGlossy, kGlossyBounds}};
  for (const auto& [scene, bounds] : cases) {
    const relight::ModelMaps maps = fitted_maps(scene, scene == sim::RtiScene::kGlossy);
    for (const auto& [gpu, cpu] : renders(maps)) {
      EXPECT_TRUE(within(difference(gpu, cpu), bounds));
      for (const double scale : {2.0, 0.5, M_PI, 1 / M_PI, 1.1, 1 / 1.1}) {
        Image scaled = gpu;
        for (float& v : scaled.pixels) v = float(v * scale);
        EXPECT_FALSE(within(difference(scaled, cpu), bounds))
            << sim::to_string(scene) << " scaled by " << scale;
      }
    }
  }
}

// Under uniform light the split sum is exact (the prefiltered radiance is that constant), as is
// SH9 irradiance and the Oren-Nayar term: what is left is the tables' sampling and interpolation
// and the reference's 2048 discrete lights.
TEST_F(PrefilteredModels, UniformLightIsExactUpToTheTables) {
  const physics::EnvironmentMap uniform(Image(64, 32, 3, 1.0f));
  relight::EnvironmentSampling sampling;
  sampling.directions_width = 64;
  ViewLighting lighting;
  lighting.lights = relight::LightingForModels::environment(uniform, 0.0, sampling);
  // Per model (Lambert, Oren-Nayar, +Torrance-Sparrow, +Phong), measured max 5.1e-4, 6.5e-3,
  // 0.25 (one pixel at cos_o 0.02), 2.4e-3; mean 7.7e-5, 4.4e-4, 5.8e-3, 2.5e-4.
  const double max_bound[] = {0, 2e-3, 2e-2, 0.4, 1e-2};
  const double mean_bound[] = {0, 5e-4, 2e-3, 2e-2, 1e-3};
  for (const int model : {1, 2, 3, 4}) {
    const relight::ModelMaps maps = one_model(model, 3);
    const auto source = upload_models(maps, {}, ModelShading::kPrefiltered);
    const ImageDifference d =
        difference(gpu_render(*source, lighting), relight::render_models(maps, lighting.lights));
    std::cout << "prefiltered, uniform light, model " << model << ": max " << d.max_relative
              << ", mean " << d.mean_relative << "\n";
    EXPECT_LT(d.max_relative, max_bound[model]) << "model " << model;
    EXPECT_LT(d.mean_relative, mean_bound[model]) << "model " << model;
  }
}

// Per model on the synthetic maps (random normals, many oblique) under the studio: what each
// approximation costs, and the automatic choice (prefiltered under an environment, exact under a
// point light).
TEST_F(PrefilteredModels, EveryModelAndTheAutomaticChoice) {
  const ViewLighting lighting = studio(200);
  // Measured max 0.080, 0.098, 0.39, 0.092; mean 0.14, 0.15, 0.38, 0.16 (Lambert, Oren-Nayar,
  // +Torrance-Sparrow, +Phong). The Torrance-Sparrow lobe at oblique views is the weak point.
  const double max_bound[] = {0, 0.12, 0.15, 0.55, 0.15};
  const double mean_bound[] = {0, 0.2, 0.2, 0.5, 0.22};
  for (const int model : {1, 2, 3, 4}) {
    const relight::ModelMaps maps = one_model(model, 11);
    const auto source = upload_models(maps, {}, ModelShading::kAuto);
    const ImageDifference d =
        difference(gpu_render(*source, lighting), relight::render_models(maps, lighting.lights));
    EXPECT_NE(source->note().find("prefiltered"), std::string::npos) << source->note();
    std::cout << "prefiltered, model " << model << ": max " << d.max_relative << ", mean "
              << d.mean_relative << "\n";
    EXPECT_LT(d.max_relative, max_bound[model]) << "model " << model;
    EXPECT_LT(d.mean_relative, mean_bound[model]) << "model " << model;
    // A point light stays exact.
    const ViewLighting point = point_light();
    const ImageDifference exact =
        difference(gpu_render(*source, point), relight::render_models(maps, point.lights));
    EXPECT_EQ(source->note().find("prefiltered"), std::string::npos) << source->note();
    EXPECT_LT(exact.max_relative, 1e-4);  // As ModelsMatchTheCpuUnderAnEnvironmentAndAPointLight.
  }
}

TEST_F(GpuRelight, WrongLightingOrTargetSizeIsAnInputError) {
  const auto source = upload_field(*field_);
  ViewLighting lighting = environment(0);
  lighting.led_irradiance_rgb.resize(3 * 39);
  GpuTarget target(64, 48);
  EXPECT_THROW(source->render(lighting, target), InputError);
  GpuTarget wrong(32, 48);
  EXPECT_THROW(source->render(environment(0), wrong), InputError);
}

TEST_F(GpuRelight, DrawToScreenAppliesExposureAndSrgbAndSplits) {
  // Left half 0.25 (field units), right half from a second target at 0.5; exposure +1 stop.
  GpuTarget a(64, 48), b(64, 48);
  {
    relight::ModelMaps flat = synthetic_maps(64, 48, 1);
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 64; ++x) flat.maps.at(x, y, relight::kMapModel) = 0;  // All flagged.
    }
    Image quarter(64, 48, 3, 0.25f), half(64, 48, 3, 0.5f);
    relight::ModelRenderOptions options;
    options.flagged_fallback = &quarter;
    upload_models(flat, options)->render(environment(0), a);
    options.flagged_fallback = &half;
    upload_models(flat, options)->render(environment(0), b);
  }
  DisplayOptions display;
  display.exposure_stops = 1.0;
  display.split = &b;
  display.divider = 0.5;
  GpuTarget screen(64, 48);
  GLint previous = 0;
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &previous);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, screen.framebuffer());
  draw_to_screen(a, display, 0, 0, 64, 48);
  display.difference = true;
  const Image split = screen.read_back();
  draw_to_screen(a, display, 0, 0, 64, 48);
  const Image diff = screen.read_back();
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(previous));
  // 0.25 * 2 = 0.5 -> sRGB 0.7354; 0.5 * 2 = 1 -> 1; |0.25 - 0.5| * 2 = 0.5 -> 0.7354.
  EXPECT_NEAR(split.at(10, 20, 0), 0.7354, 1e-3);
  EXPECT_NEAR(split.at(50, 20, 0), 1.0, 1e-3);
  EXPECT_NEAR(split.at(32, 20, 0), 0.9, 1e-3);  // The divider line.
  EXPECT_NEAR(diff.at(10, 20, 0), 0.7354, 1e-3);
  EXPECT_NEAR(diff.at(50, 20, 0), 0.7354, 1e-3);
}

// Without a display GLFW cannot start: a HardwareError that says what to do. (Its own suite: the
// fixture's window would keep GLFW initialised.)
TEST(GlWindow, WithoutADisplayThrowsAHardwareErrorThatSaysWhatToDo) {
  const char* display = std::getenv("DISPLAY");
  const std::optional<std::string> saved =
      display ? std::optional<std::string>(display) : std::nullopt;
  unsetenv("DISPLAY");
  try {
    GlWindow window(32, 32, "no display", false);
    ADD_FAILURE() << "a window opened without DISPLAY";
  } catch (const HardwareError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("no display"), std::string::npos) << message;
    EXPECT_NE(message.find("xvfb-run"), std::string::npos) << message;
  }
  if (saved) setenv("DISPLAY", saved->c_str(), 1);
  // And with the display back, a window opens.
  if (saved) {
    GlWindow window(32, 32, "display back", false);
    EXPECT_FALSE(window.renderer().empty());
  }
}

}  // namespace
}  // namespace ls::viewer
