// Model-based relighting (relight/fit/model_render.h) and model map I/O, against the simulator's
// ground truth and against field relighting, on three spheres of known materials.
#include "relight/fit/model_render.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>
#include <numbers>

#include "lightstage/errors.h"
#include "lightstage/image_metrics.h"
#include "lightstage/stage.h"
#include "relight/lighting/relight.h"
#include "sim/ground_truth.h"
#include "sim/region_materials.h"
#include "sim/sim_stage.h"
#include "tests/relight/fit/fit_fixtures.h"
#include "tests/support/test_support.h"

namespace ls::relight {
namespace {

using fit_testing::render_field;
using fit_testing::SimField;

// sim::three_region_spheres(): matte (Lambert), rough (Oren-Nayar, sigma 30 deg), glossy (Lambert +
// Torrance-Sparrow) spheres in a row. Object index = sphere index.
using sim::kGlossy;
using sim::kMatte;
using sim::kRough;

// 1 where the camera sees `object` (any object when -1) with n.v above min_cos_view.
Image region_mask(const std::vector<sim::SurfaceHit>& hits, int width, int height, int object,
                  double min_cos_view = -1) {
  Image mask(width, height, 1);
  for (const sim::SurfaceHit& h : hits) {
    if (!h.hit || (object >= 0 && h.object != object)) continue;
    if (h.normal.dot(h.wo) <= min_cos_view) continue;
    mask.at(h.pixel_x, h.pixel_y, 0) = 1;
  }
  return mask;
}

physics::EnvironmentMap shipped_map(const std::string& name) {
  return physics::EnvironmentMap::load(testing::source_dir() / "data" / "envmaps" /
                                       (name + ".exr"));
}

class ModelRender : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    stage_ = new Stage(stage_with_directions(fibonacci_dome_directions(150, -11.5)));
    stage_->camera.width = 96;
    stage_->camera.height = 32;
    stage_->camera.fov_y_deg = 0.0;
    stage_->camera.ortho_height_m = 0.9;
    const FitOptions options;
    sim_ =
        new SimField(render_field(*stage_, sim::three_region_spheres(), options.normals.noise, 21));
    maps_ = new ModelMaps(fit_models(sim_->field, options));
    std::cout << maps_->summary.to_string() << "\n";
  }
  static void TearDownTestSuite() {
    delete maps_;
    delete sim_;
    delete stage_;
  }
  static Image mask(int object, double min_cos_view = -1) {
    return region_mask(sim_->hits, stage_->camera.width, stage_->camera.height, object,
                       min_cos_view);
  }

  static Stage* stage_;
  static SimField* sim_;
  static ModelMaps* maps_;
};
Stage* ModelRender::stage_ = nullptr;
SimField* ModelRender::sim_ = nullptr;
ModelMaps* ModelRender::maps_ = nullptr;

// A smaller fit for the tests that check mechanics rather than accuracy (each test binary run
// re-creates its fixture under ctest).
class SmallFit : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    Stage stage = stage_with_directions(fibonacci_dome_directions(80, -11.5));
    stage.camera.width = 48;
    stage.camera.height = 16;
    stage.camera.fov_y_deg = 0.0;
    stage.camera.ortho_height_m = 0.9;
    const FitOptions options;
    const SimField sim = render_field(stage, sim::three_region_spheres(), options.normals.noise, 5);
    maps_ = new ModelMaps(fit_models(sim.field, options));
  }
  static void TearDownTestSuite() { delete maps_; }
  static ModelMaps* maps_;
};
ModelMaps* SmallFit::maps_ = nullptr;

TEST_F(ModelRender, LambertRegionMatchesGroundTruthAndTheGridConverges) {
  const physics::EnvironmentMap map = shipped_map("softbox_studio");
  sim::GroundTruthOptions truth_options;
  truth_options.directions_width = 128;
  // The matte sphere alone: the same pixels, with no neighbours to cast shadows the models cannot.
  sim::Scene matte_alone = sim::three_region_spheres();
  matte_alone.spheres.resize(1);
  const Image truth = sim::render_ground_truth(matte_alone, stage_->camera, map, truth_options);
  const Image truth_with_neighbours =
      sim::render_ground_truth(sim::three_region_spheres(), stage_->camera, map, truth_options);
  const Image matte = mask(kMatte);
  // The models without the shadows their fit measured: lit as if the neighbours were not there.
  ModelMaps unshadowed = *maps_;
  unshadowed.shadows = {};
  double error_at[4] = {};
  const int widths[4] = {16, 32, 64, 128};
  for (int i = 0; i < 4; ++i) {
    const Image rendered =
        render_models(unshadowed, LightingForModels::environment(map, 0.0, {widths[i]}));
    error_at[i] = compare_images(rendered, truth, &matte).relative_rmse;
    std::cout << "softbox, matte sphere, grid " << widths[i] << ": relative RMSE " << error_at[i]
              << "\n";
  }
  const auto beside_neighbours = [&](const ModelMaps& maps) {
    return compare_images(render_models(maps, LightingForModels::environment(map, 0.0, {64})),
                          truth_with_neighbours, &matte)
        .relative_rmse;
  };
  const double shadowed = beside_neighbours(*maps_);
  const double unshadowed_beside = beside_neighbours(unshadowed);
  std::cout << "softbox, matte sphere beside its neighbours, grid 64: relative RMSE " << shadowed
            << " with the fit's shadows, " << unshadowed_beside << " without\n";
  // Measured: 0.0175, 0.0052, 0.0041, 0.0038 for grids 16..128 (what remains is fit noise and
  // the truth's own 128-wide quadrature); beside the neighbours 0.0057 with the shadows, 0.031
  // without (the neighbours' shadows missing).
  EXPECT_LT(error_at[2], 0.01);
  EXPECT_LT(error_at[3], 0.01);
  EXPECT_LE(error_at[2], error_at[0]);
  EXPECT_LT(shadowed, 0.01);
  EXPECT_GT(unshadowed_beside, 3 * shadowed);
}

TEST_F(ModelRender, AgainstFieldRelightingAndGroundTruth) {
  const std::vector<Eigen::Vector3d> dirs = stage_->led_directions();
  const Image spheres = mask(-1);
  int non_physical = 0;
  for (const sim::SurfaceHit& h : sim_->hits)
    non_physical += maps_->at(h.pixel_x, h.pixel_y, kMapKs) > 1;
  for (const std::string name : {"softbox_studio", "sky_sun"}) {
    const physics::EnvironmentMap map = shipped_map(name);
    sim::GroundTruthOptions full;
    full.directions_width = 128;
    sim::GroundTruthOptions covered = full;
    covered.covered_by_leds = dirs;
    const Image truth =
        sim::render_ground_truth(sim::three_region_spheres(), stage_->camera, map, full);
    const Image truth_covered =
        sim::render_ground_truth(sim::three_region_spheres(), stage_->camera, map, covered);
    const LightWeights weights = integrate_environment(map, dirs);
    const Image field_relit = relight(sim_->field, weights);
    EnvironmentSampling dome;
    dome.covered_by_leds = dirs;
    const Image models_dome = render_models(*maps_, LightingForModels::environment(map, 0.0, dome));
    const Image models_sphere = render_models(*maps_, LightingForModels::environment(map, 0.0));
    const Image models_leds = render_models(*maps_, LightingForModels::led_cells(dirs, weights));
    ModelRenderOptions unguarded;
    unguarded.max_specular_albedo = std::numeric_limits<float>::infinity();
    const Image models_unguarded =
        render_models(*maps_, LightingForModels::environment(map, 0.0, dome), unguarded);
    auto error = [&](const Image& a, const Image& b) {
      return compare_images(a, b, &spheres).relative_rmse;
    };
    const double field_vs_truth = error(field_relit, truth_covered);
    const double dome_vs_truth = error(models_dome, truth_covered);
    const double leds_vs_truth = error(models_leds, truth_covered);
    const double leds_vs_field = error(models_leds, field_relit);
    const double sphere_vs_truth = error(models_sphere, truth);
    std::cout << name << ", sphere pixels, relative RMSE against the truth over the dome's "
              << "coverage: field " << field_vs_truth << ", models (64-wide grid) " << dome_vs_truth
              << ", models (at the LEDs) " << leds_vs_truth << "; models (at the LEDs) vs field "
              << leds_vs_field << "; whole sphere of light, models vs truth " << sphere_vs_truth
              << "; without the k_s guard (" << non_physical << " pixels have k_s > 1) "
              << error(models_unguarded, truth_covered) << "\n";
    // Measured: softbox 0.038 field, 0.045 models (grid), 0.058 models (LEDs), 0.042 models vs
    // field, 0.046 whole sphere; sky_sun 0.062, 0.089, 0.106, 0.092, 0.098. Without the render
    // guard: the same (0.045, 0.089), since fit_models discards lobes with k_s > 2 (5 pixels
    // keep k_s in (1, 2]); with those lobes kept, 17 and 265. The models lose to the field by what
    // they cannot have: the shadows the spheres cast on each other (the sun makes them sharp) and
    // misfit near the silhouettes.
    EXPECT_LT(field_vs_truth, 0.1) << name;
    EXPECT_LT(dome_vs_truth, 0.15) << name;
    EXPECT_LT(leds_vs_truth, 0.16) << name;
    EXPECT_LT(leds_vs_field, 0.14) << name;
    EXPECT_LT(sphere_vs_truth, 0.15) << name;
    for (const float v : models_sphere.pixels) ASSERT_TRUE(std::isfinite(v));
  }
}

TEST_F(ModelRender, DirectionalLightMatchesTheOneLightTruthPerRegion) {
  // A direction between LEDs, up and to the right of the camera: every sphere has a highlight.
  const Eigen::Vector3d dir = Eigen::Vector3d(0.35, 0.45, 0.82).normalized();
  const Image truth = sim::render_one_light(sim::three_region_spheres(), sim_->hits, dir);
  const Image rendered =
      render_models(*maps_, LightingForModels::directional(dir, Eigen::Vector3d(1, 1, 1)));
  const char* names[3] = {"matte", "rough", "glossy"};
  double error[3];
  for (int r = 0; r < 3; ++r) {
    const Image m = mask(r, 0.3);
    error[r] = compare_images(rendered, truth, &m).relative_rmse;
    std::cout << "directional light, " << names[r] << " front: relative RMSE " << error[r] << "\n";
  }
  // Measured: 0.0041 / 0.0061 / 0.0055.
  EXPECT_LT(error[kMatte], 0.01);
  EXPECT_LT(error[kRough], 0.03);
  EXPECT_LT(error[kGlossy], 0.03);
  // Scaling the light scales the render exactly (linear in E).
  const Image doubled =
      render_models(*maps_, LightingForModels::directional(dir, Eigen::Vector3d(2, 2, 2)));
  for (size_t i = 0; i < doubled.pixels.size(); ++i) {
    ASSERT_NEAR(doubled.pixels[i], 2 * rendered.pixels[i], 1e-5f * (1 + rendered.pixels[i]));
  }
}

TEST_F(SmallFit, FlaggedPixelsAreBlackOrTakenFromTheFallback) {
  const LightingForModels lighting =
      LightingForModels::directional(Eigen::Vector3d(0, 1, 1), Eigen::Vector3d(1, 1, 1));
  const Image black = render_models(*maps_, lighting);
  Image fallback(black.width, black.height, 3, 0.25f);
  ModelRenderOptions options;
  options.flagged_fallback = &fallback;
  const Image filled = render_models(*maps_, lighting, options);
  int flagged = 0;
  for (int y = 0; y < black.height; ++y) {
    for (int x = 0; x < black.width; ++x) {
      const bool is_flagged = maps_->model(x, y) == FitModel::kNone;
      flagged += is_flagged;
      for (int c = 0; c < 3; ++c) {
        if (is_flagged) {
          EXPECT_EQ(black.at(x, y, c), 0.0f);
          EXPECT_EQ(filled.at(x, y, c), 0.25f);
        } else {
          EXPECT_EQ(filled.at(x, y, c), black.at(x, y, c));
        }
      }
    }
  }
  EXPECT_GT(flagged, 0);  // The background.
  Image wrong_size(4, 4, 3);
  options.flagged_fallback = &wrong_size;
  EXPECT_THROW(render_models(*maps_, lighting, options), InputError);
  EXPECT_THROW(LightingForModels::environment(shipped_map("sky_sun"), 0.0, {7}), InputError);
}

TEST_F(SmallFit, ModelMapsRoundTripBitExactly) {
  testing::TempDir dir;
  ModelMaps maps = *maps_;
  maps.noise = {2.5e-9, 9.75e-6};
  maps.noise_source = "measured (test)";
  write_model_maps(dir / "maps.exr", maps);
  const ModelMaps back = read_model_maps(dir / "maps.exr");
  ASSERT_EQ(back.maps.width, maps.maps.width);
  ASSERT_EQ(back.maps.height, maps.maps.height);
  ASSERT_EQ(back.maps.channels, maps.maps.channels);
  EXPECT_EQ(back.maps.channel_names, maps.maps.channel_names);
  ASSERT_EQ(back.maps.pixels.size(), maps.maps.pixels.size());
  EXPECT_EQ(std::memcmp(back.maps.pixels.data(), maps.maps.pixels.data(),
                        maps.maps.pixels.size() * sizeof(float)),
            0);
  EXPECT_EQ(back.noise.a, maps.noise.a);
  EXPECT_EQ(back.noise.b, maps.noise.b);
  EXPECT_EQ(back.noise_source, maps.noise_source);
  EXPECT_EQ(back.summary.fitted, maps.summary.fitted);
  EXPECT_EQ(back.summary.flagged, maps.summary.flagged);
  for (int m = 0; m < 5; ++m) EXPECT_EQ(back.summary.per_model[m], maps.summary.per_model[m]);
  // The fit's shadows, some LEDs of some pixels in shadow; maps without them read as unshadowed.
  ASSERT_FALSE(maps.shadows.empty());
  EXPECT_TRUE(std::any_of(maps.shadows.words.pixels.begin(), maps.shadows.words.pixels.end(),
                          [](float w) { return w != 0; }));
  EXPECT_EQ(back.shadows.words.pixels, maps.shadows.words.pixels);
  EXPECT_EQ(back.shadows.led_dirs_in_stage, maps.shadows.led_dirs_in_stage);
  maps.shadows = {};
  write_model_maps(dir / "unshadowed.exr", maps);
  EXPECT_TRUE(read_model_maps(dir / "unshadowed.exr").shadows.empty());
}

TEST_F(SmallFit, ReadModelMapsNamesTheFileAndTheChannel) {
  testing::TempDir dir;
  ModelMaps maps = *maps_;
  maps.maps.at(5, 7, kMapModel) = 9;
  write_model_maps(dir / "bad_model.exr", maps);
  try {
    read_model_maps(dir / "bad_model.exr");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("bad_model.exr"), std::string::npos) << message;
    EXPECT_NE(message.find("channel 'model'"), std::string::npos) << message;
    EXPECT_NE(message.find("(5, 7)"), std::string::npos) << message;
  }
  // A flags value no int holds (fuzz/model_maps_fuzz: converting it was undefined behaviour).
  maps = *maps_;
  maps.maps.at(5, 7, kMapFlags) = 1.28889e30f;
  write_model_maps(dir / "bad_flags.exr", maps);
  try {
    read_model_maps(dir / "bad_flags.exr");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("bad_flags.exr: channel 'flags': expected flag bits"), std::string::npos)
        << message;
    EXPECT_NE(message.find("(5, 7)"), std::string::npos) << message;
  }
  // A material's pixel count no int holds (the same: its conversion was undefined behaviour).
  Image named = maps_->maps;
  named.channel_names = model_map_channel_names();
  write_exr(dir / "bad_material.exr", named, ExrPixelType::kFloat,
            {{"lightstage:materials", R"([{"model": "lambert", "albedo": [0.5, 0.5, 0.5],
                                          "sigma": 0, "ks": 0, "roughness": 0, "pixels": 1e40}])"}});
  try {
    read_model_maps(dir / "bad_material.exr");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("bad_material.exr: attribute 'lightstage:materials': material 1: "
                           "pixels: expected an integer, got 1e+40"),
              std::string::npos)
        << message;
  }
  // A shadow word beyond its 24 bits, and shadows for other LEDs than the attribute lists.
  maps = *maps_;
  maps.shadows.words.at(2, 3, 1) = 0.5f;
  write_model_maps(dir / "bad_shadow.exr", maps);
  try {
    read_model_maps(dir / "bad_shadow.exr");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("bad_shadow.exr: channel 'shadow.1': expected an integer in 0..16777215 "
                           "at (2, 3), got 0.5"),
              std::string::npos)
        << message;
  }
  maps = *maps_;
  maps.shadows.led_dirs_in_stage.resize(8);
  write_model_maps(dir / "shadow_leds.exr", maps);
  try {
    read_model_maps(dir / "shadow_leds.exr");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("shadow_leds.exr: channels 'shadow.N': expected 1 for the 8 LEDs of "
                           "attribute 'lightstage:shadow_leds', got 10"),
              std::string::npos)
        << message;
  }
  write_exr(dir / "rgb.exr", Image(4, 4, 3));
  try {
    read_model_maps(dir / "rgb.exr");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("rgb.exr"), std::string::npos) << message;
    EXPECT_NE(message.find("channel 'normal.x'"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace ls::relight
