// Edits of fitted model maps (relight/fit/model_edit.h), the edit file's validation, and the CLI
// path `lightstage fit` -> `lightstage relight --models --edits`.
#include "relight/fit/model_edit.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "lightstage/stage.h"
#include "relight/fit/model_render.h"
#include "sim/region_materials.h"
#include "sim/sim_stage.h"
#include "tests/app/e2e_fixtures.h"
#include "tests/relight/fit/fit_fixtures.h"
#include "tests/support/test_support.h"

namespace ls::relight {
namespace {

namespace fs = std::filesystem;
using fit_testing::render_field;
using fit_testing::SimField;

// The matte, rough and glossy spheres of sim::three_region_spheres(); object index = region.
using sim::kGlossy;
using sim::kMatte;
using sim::kRough;

Stage small_stage(int leds, int width, int height) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(leds, -11.5));
  stage.camera.width = width;
  stage.camera.height = height;
  stage.camera.fov_y_deg = 0.0;
  stage.camera.ortho_height_m = 0.9;
  return stage;
}

ModelEdits edits_from(const std::string& json, const fs::path& dir, int width, int height) {
  return parse_model_edits(json, "edits.json", dir, width, height);
}

// The message of the InputError `f` throws ("" when it throws none).
template <class F>
std::string input_error_of(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

class EditedModels : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const Stage stage = small_stage(150, 48, 16);
    const FitOptions options;
    sim_ = new SimField(render_field(stage, sim::three_region_spheres(), options.normals.noise, 7));
    maps_ = new ModelMaps(fit_models(sim_->field, options));
    std::cout << maps_->summary.to_string() << "\n";
  }
  static void TearDownTestSuite() {
    delete maps_;
    delete sim_;
  }
  static int width() { return maps_->maps.width; }
  static int height() { return maps_->maps.height; }
  // A light from up and to the right: highlights on the glossy sphere.
  static LightingForModels key_light() {
    return LightingForModels::directional(Eigen::Vector3d(0.3, 0.4, 0.87),
                                          Eigen::Vector3d(1, 1, 1));
  }
  static ModelMaps edited(const std::string& json, const fs::path& dir = ".") {
    ModelMaps maps = *maps_;
    apply_model_edits(edits_from(json, dir, width(), height()), maps);
    return maps;
  }

  static SimField* sim_;
  static ModelMaps* maps_;
};
SimField* EditedModels::sim_ = nullptr;
ModelMaps* EditedModels::maps_ = nullptr;

TEST_F(EditedModels, TintByModelClassScalesOnlyThatClassDiffuseOutput) {
  const Eigen::Vector3d tint(0.5, 0.8, 1.2);
  // Lambert pixels have no lobe: their whole output is diffuse.
  const ModelMaps tinted = edited(R"({"edits": [{"select": {"model": "lambert"},
                                                 "albedo_tint": [0.5, 0.8, 1.2]}]})");
  const Image before = render_models(*maps_, key_light());
  const Image after = render_models(tinted, key_light());
  int lambert_pixels = 0;
  for (int y = 0; y < height(); ++y) {
    for (int x = 0; x < width(); ++x) {
      const bool lambert = maps_->model(x, y) == FitModel::kLambert;
      lambert_pixels += lambert;
      for (int c = 0; c < 3; ++c) {
        const float expected = lambert ? float(tint[c]) * before.at(x, y, c) : before.at(x, y, c);
        ASSERT_NEAR(after.at(x, y, c), expected, 1e-6f * (1 + before.at(x, y, c)))
            << "(" << x << ", " << y << ") model " << to_string(maps_->model(x, y));
      }
    }
  }
  EXPECT_GT(lambert_pixels, 50);
  // Glossy pixels: with k_s = 0 on both sides, the tint scales the (diffuse) output exactly, and
  // no other pixel changes.
  const std::string no_lobe = R"({"select": {"model": "torrance_sparrow"}, "specular_scale": 0})";
  const ModelMaps diffuse = edited(R"({"edits": [)" + no_lobe + "]}");
  const ModelMaps diffuse_tinted = edited(R"({"edits": [)" + no_lobe +
                                          R"(, {"select": {"model": "torrance_sparrow"},
                                                "albedo_tint": [0.5, 0.8, 1.2]}]})");
  const Image d0 = render_models(diffuse, key_light());
  const Image d1 = render_models(diffuse_tinted, key_light());
  int glossy_pixels = 0;
  for (int y = 0; y < height(); ++y) {
    for (int x = 0; x < width(); ++x) {
      const bool glossy = maps_->model(x, y) == FitModel::kLambertTorranceSparrow;
      glossy_pixels += glossy && d0.at(x, y, 0) > 0;
      for (int c = 0; c < 3; ++c) {
        const float expected = glossy ? float(tint[c]) * d0.at(x, y, c) : d0.at(x, y, c);
        ASSERT_NEAR(d1.at(x, y, c), expected, 1e-6f * (1 + d0.at(x, y, c)));
      }
    }
  }
  EXPECT_GT(glossy_pixels, 20);
}

TEST_F(EditedModels, RoughnessAndSpecularScaleChangeOnlyGlossyPixels) {
  const ModelMaps maps = edited(R"({"edits": [{"select": {"model": "torrance_sparrow"},
                                               "roughness_scale": 1.5, "specular_scale": 0.5}]})");
  const Image before = render_models(*maps_, key_light());
  const Image after = render_models(maps, key_light());
  int changed_glossy = 0;
  float peak_before = 0, peak_after = 0;
  for (int y = 0; y < height(); ++y) {
    for (int x = 0; x < width(); ++x) {
      const bool glossy = maps_->model(x, y) == FitModel::kLambertTorranceSparrow;
      if (!glossy) {
        for (int c = 0; c < kMapChannelCount; ++c) {
          ASSERT_EQ(maps.maps.at(x, y, c), maps_->maps.at(x, y, c));
        }
        for (int c = 0; c < 3; ++c) ASSERT_EQ(after.at(x, y, c), before.at(x, y, c));
        continue;
      }
      EXPECT_FLOAT_EQ(maps.at(x, y, kMapKs), 0.5f * maps_->at(x, y, kMapKs));
      EXPECT_FLOAT_EQ(maps.at(x, y, kMapRoughness),
                      std::clamp(1.5f * maps_->at(x, y, kMapRoughness), 0.02f, 1.0f));
      changed_glossy += after.at(x, y, 0) != before.at(x, y, 0);
      peak_before = std::max(peak_before, before.at(x, y, 0));
      peak_after = std::max(peak_after, after.at(x, y, 0));
    }
  }
  EXPECT_GT(changed_glossy, 20);
  // A rougher, weaker lobe: a dimmer highlight. Measured: peak 0.85 -> 0.33.
  std::cout << "highlight peak (R) " << peak_before << " -> " << peak_after << "\n";
  EXPECT_LT(peak_after, 0.8 * peak_before);
}

TEST_F(EditedModels, SwappingTheGlossySphereToLambertRemovesTheHighlight) {
  testing::TempDir dir;
  // The glossy sphere's mask, from the simulator's hits.
  Image mask(width(), height(), 1);
  for (const sim::SurfaceHit& h : sim_->hits) {
    if (h.hit && h.object == kGlossy) mask.at(h.pixel_x, h.pixel_y, 0) = 1;
  }
  write_png_preview(dir / "glossy.png", mask);
  const ModelMaps matte = edited(R"({"edits": [{"select": {"mask": "glossy.png"},
                                                "set_model": {"model": "lambert"}}]})",
                                 dir.path());
  const ModelMaps no_lobe = edited(R"({"edits": [{"select": {"model": "torrance_sparrow"},
                                                  "specular_scale": 0}]})");
  const Image before = render_models(*maps_, key_light());
  const Image after = render_models(matte, key_light());
  const Image diffuse = render_models(no_lobe, key_light());
  double highlight_before = 0, highlight_after = 0;
  int swapped = 0;
  for (int y = 0; y < height(); ++y) {
    for (int x = 0; x < width(); ++x) {
      if (mask.at(x, y, 0) == 0 || maps_->model(x, y) == FitModel::kNone) continue;
      EXPECT_EQ(matte.model(x, y), FitModel::kLambert);
      EXPECT_EQ(matte.at(x, y, kMapKs), 0.0f);
      swapped += maps_->model(x, y) == FitModel::kLambertTorranceSparrow;
      // Green: the lobe is white and the albedo's green is low, so the highlight stands out.
      highlight_before =
          std::max(highlight_before, double(before.at(x, y, 1) - diffuse.at(x, y, 1)));
      highlight_after = std::max(highlight_after, double(after.at(x, y, 1) - diffuse.at(x, y, 1)));
    }
  }
  std::cout << swapped
            << " glossy pixels swapped; highlight above diffuse (G): " << highlight_before << " -> "
            << highlight_after << "\n";
  // Measured: 135 pixels swapped, highlight 0.68 -> 4e-9 (float rounding).
  EXPECT_GT(swapped, 20);
  EXPECT_GT(highlight_before, 0.05);
  EXPECT_LT(highlight_after, 1e-6);
  // Giving the matte sphere a lobe makes it glossy: a highlight appears there.
  const ModelMaps glossy = edited(R"({"edits": [{"select": {"model": "lambert"},
      "set_model": {"model": "torrance_sparrow", "ks": 0.3, "roughness": 0.15}}]})");
  const Image shiny = render_models(glossy, key_light());
  double added = 0;
  for (int y = 0; y < height(); ++y) {
    for (int x = 0; x < width(); ++x) {
      if (maps_->model(x, y) != FitModel::kLambert) continue;
      EXPECT_EQ(glossy.model(x, y), FitModel::kLambertTorranceSparrow);
      added = std::max(added, double(shiny.at(x, y, 1) - before.at(x, y, 1)));
    }
  }
  EXPECT_GT(added, 0.05);
}

TEST_F(EditedModels, ParametersAreClampedToTheirBounds) {
  const ModelMaps maps = edited(R"({"edits": [
      {"select": {"model": "torrance_sparrow"}, "roughness_scale": 1000, "albedo_tint": [100, 0, 1]},
      {"select": {"model": "oren_nayar"}, "sigma_scale": 1000}]})");
  for (int y = 0; y < height(); ++y) {
    for (int x = 0; x < width(); ++x) {
      if (maps_->model(x, y) == FitModel::kLambertTorranceSparrow) {
        EXPECT_EQ(maps.at(x, y, kMapRoughness), 1.0f);
        EXPECT_EQ(maps.at(x, y, kMapAlbedoR), std::max(1.0f, maps_->at(x, y, kMapAlbedoR)));
        EXPECT_EQ(maps.at(x, y, kMapAlbedoG), 0.0f);
      }
      if (maps_->model(x, y) == FitModel::kOrenNayar) {
        EXPECT_FLOAT_EQ(maps.at(x, y, kMapSigma), float(0.5 * physics::brdf::kPi));
      }
    }
  }
}

// "Make this material rougher": the edit reaches every pixel of the glossy sphere's material, the
// ones whose own fit was Lambert included (lower half), and no other pixel.
TEST_F(EditedModels, RougherByMaterialChangesExactlyThatMaterialsPixels) {
  int glossy = 0;
  for (size_t k = 0; k < maps_->materials.size(); ++k) {
    if (maps_->materials[k].model == FitModel::kLambertTorranceSparrow) glossy = int(k) + 1;
  }
  ASSERT_GT(glossy, 0) << "no glossy basis material";
  const ModelMaps rougher = edited(R"({"edits": [{"select": {"material": )" +
                                   std::to_string(glossy) + R"(}, "roughness_scale": 2}]})");
  int members = 0;
  for (int y = 0; y < height(); ++y) {
    for (int x = 0; x < width(); ++x) {
      const bool member = int(maps_->at(x, y, kMapMaterial)) == glossy;
      members += member;
      const float before = maps_->at(x, y, kMapRoughness);
      const float expected = member ? std::min(1.0f, 2 * before) : before;
      ASSERT_FLOAT_EQ(rougher.at(x, y, kMapRoughness), expected) << x << ", " << y;
    }
  }
  EXPECT_EQ(members, maps_->materials[size_t(glossy - 1)].pixels);
  // A material the maps do not have names the edit file and the field.
  ModelMaps maps = *maps_;
  const std::string message = input_error_of([&] {
    apply_model_edits(edits_from(R"({"edits": [{"select": {"material": 40}, "sigma_scale": 2}]})",
                                 ".", width(), height()),
                      maps);
  });
  EXPECT_NE(message.find("edits.json: edits[0].select.material: expected 1.."), std::string::npos)
      << message;
}

TEST_F(EditedModels, BadEditFilesNameTheFileAndTheField) {
  testing::TempDir dir;
  write_png_preview(dir / "small.png", Image(4, 4, 1, 1.0f));
  auto error_of = [&](const std::string& json) {
    write_file_atomic(dir / "edits.json", json);
    return input_error_of([&] { read_model_edits(dir / "edits.json", width(), height()); });
  };
  const std::string wrong_size = error_of(R"({"edits": [
      {"select": {"model": "lambert"}, "albedo_tint": [1, 1, 1]},
      {"select": {"mask": "small.png"}, "albedo_tint": [1, 0, 0]}]})");
  EXPECT_NE(wrong_size.find("edits.json: edits[1].select.mask"), std::string::npos) << wrong_size;
  EXPECT_NE(wrong_size.find("48x16"), std::string::npos) << wrong_size;
  const std::string unknown_model = error_of(R"({"edits": [
      {"select": {"model": "lambert"}, "albedo_tint": [1, 1, 1]},
      {"select": {"model": "glossy"}, "specular_scale": 2}]})");
  EXPECT_NE(unknown_model.find("edits.json: edits[1].select.model"), std::string::npos)
      << unknown_model;
  EXPECT_NE(unknown_model.find("torrance_sparrow"), std::string::npos) << unknown_model;
  for (const std::string& json :
       {std::string(R"({"edits": [{"select": {}}]})"),
        std::string(R"({"edits": [{"select": {"model": "lambert"}, "tint": [1, 1, 1]}]})"),
        std::string(R"({"edits": [{"select": {"model": "lambert"}, "roughness_scale": 0}]})"),
        std::string(R"({"edits": [{"select": {"model": "lambert"},
                        "set_model": {"model": "torrance_sparrow", "ks": 0.3}}]})"),
        std::string(R"({"edits": [{"select": {"model": "lambert"},
                        "set_model": {"model": "lambert", "ks": 0.3}}]})"),
        std::string(R"({"edits": [{"select": {"mask": "missing.png"}}]})"),
        std::string(R"({"edits": [{"select": {"model": "lambert"}, "albedo_tint": [1, -1, 1]}]})"),
        std::string(R"({"edits": [)")}) {
    const std::string message = error_of(json);
    EXPECT_NE(message.find("edits.json"), std::string::npos) << json << " -> " << message;
  }
}

TEST(ModelEditCli, FitThenRelightModelsWithEditsAndABadEditFile) {
  testing::TempDir dir;
  const Stage stage = small_stage(30, 32, 12);
  const capture::ReflectanceField field =
      testing::CaptureAndBuild(dir / "session", stage, sim::three_region_spheres(), 3);
  capture::write_field(dir / "field.exr", field);
  const std::string cli = testing::cli_path().string();
  std::string out;
  ASSERT_EQ(testing::run_command(cli + " fit --quiet " + (dir / "field.exr").string() + " --out " +
                                     (dir / "maps.exr").string(),
                                 &out),
            0)
      << out;
  EXPECT_NE(out.find("lambert"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(dir / "maps.albedo.png"));
  write_file_atomic(dir / "edits.json", R"({"edits": [
      {"select": {"model": "torrance_sparrow"}, "set_model": {"model": "lambert"}},
      {"select": {"model": "lambert"}, "albedo_tint": [1, 0.5, 0.5]}]})");
  const std::string env = (testing::source_dir() / "data" / "envmaps" / "sky_sun.exr").string();
  const std::string relight = cli + " relight --quiet --models " + (dir / "maps.exr").string() +
                              " --env " + env + " --out " + (dir / "relit").string();
  ASSERT_EQ(testing::run_command(relight + " --edits " + (dir / "edits.json").string(), &out), 0)
      << out;
  for (const char* name : {"sky_sun.exr", "sky_sun.png", "contact_sheet.png"}) {
    EXPECT_TRUE(fs::exists(dir / "relit" / name)) << name;
  }
  const Image relit = read_image(dir / "relit" / "sky_sun.exr");
  EXPECT_EQ(relit.width, 32);
  for (const float v : relit.pixels) ASSERT_TRUE(std::isfinite(v));
  // A single directional light instead of a map.
  ASSERT_EQ(testing::run_command(cli + " relight --quiet --models " + (dir / "maps.exr").string() +
                                     " --light 0.3 0.5 0.8 --out " + (dir / "lit").string(),
                                 &out),
            0)
      << out;
  EXPECT_TRUE(fs::exists(dir / "lit" / "light.png"));
  write_file_atomic(dir / "bad.json", R"({"edits": [{"select": {"model": "shiny"}}]})");
  EXPECT_EQ(testing::run_command(relight + " --edits " + (dir / "bad.json").string(), &out), 2)
      << out;
  EXPECT_NE(out.find("bad.json: edits[0].select.model"), std::string::npos) << out;
}

}  // namespace
}  // namespace ls::relight
