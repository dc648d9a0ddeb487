// GPU relighting of fitted-model maps (viewer/gpu_relight.h) against the CPU's render_models:
// exact shading under an environment and a point light, in several passes, with per-pixel view
// directions, and prefiltered shading against the exact render. Runs on llvmpipe under Xvfb.
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "physics/envmap.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "tests/viewer/gpu_relight_fixture.h"
#include "viewer/gpu_relight.h"

namespace ls::viewer {
namespace {

using namespace gpu_testing;  // NOLINT(google-build-using-namespace)

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

}  // namespace
}  // namespace ls::viewer
