// The viewer under a map with a compact source (a sun rotating with the map at
// interactive rates): a field is relit by the LED cells of the map without its sources, plus each
// source at its true direction (relight::FieldSources), exactly as `lightstage relight` does, at
// every rotation; the PCA keeps the whole map. Runs under Xvfb (tests/viewer/with_xvfb.sh), where
// the viewer relights the field on the CPU (llvmpipe); the shader path (upload_field) is checked
// against the same reference directly.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <string>
#include <thread>

#include "capture/field.h"
#include "capture/field_file.h"
#include "physics/envmap.h"
#include "relight/compact/pca_field.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "relight/sources/field_sources.h"
#include "relight/sources/map_relight.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"
#include "tests/support/test_support.h"
#include "viewer/gl_window.h"
#include "viewer/gpu_relight.h"
#include "viewer/view_lighting.h"
#include "viewer/viewer_app.h"
#include "viewer/viewer_state.h"

namespace ls::viewer {
namespace {

// Largest |a - b| over the image, relative to the largest |b| (absolute when b is black: a map
// whose only light is a source outside the dome's coverage lights nothing).
double max_relative_difference(const Image& a, const Image& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.channels, b.channels);
  double peak = 0, worst = 0;
  for (float v : b.pixels) peak = std::max(peak, double(std::abs(v)));
  for (size_t i = 0; i < a.pixels.size() && i < b.pixels.size(); ++i) {
    EXPECT_TRUE(std::isfinite(a.pixels[i]));
    worst = std::max(worst, double(std::abs(a.pixels[i] - b.pixels[i])));
  }
  return peak > 0 ? worst / peak : worst;
}

Action rotate_to(double deg) {
  Action a;
  a.kind = Action::Kind::kRotate;
  a.value = deg;
  return a;
}

// A 64 x 48 simulated field of the shadowed RTI scene (40 LEDs) under small_source.exr (a 2-degree
// source), written once for the viewer to open.
class ViewerBrightSources : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir();
    Stage stage = sim::rti_dome_stage(40, 10.0, 64);
    stage.camera.height = 48;
    capture::FieldNoise noise;
    noise.read_variance = 1e-6;
    noise.shot_variance_per_unit = 1e-5;
    field_ = new capture::ReflectanceField(
        sim::render_noisy_field(stage, sim::rti_scene(sim::RtiScene::kShadowed), noise, 11));
    capture::write_field(field_path(), *field_);
    *field_ = capture::read_field(field_path());  // Exactly what the viewer reads.
    map_ = new physics::EnvironmentMap(physics::EnvironmentMap::load(map_path()));
    for (const capture::FieldLight& light : field_->lights()) {
      dirs_.push_back(light.dir_in_stage);
      valid_.push_back(light.valid);
    }
  }
  static void TearDownTestSuite() {
    delete map_;
    delete field_;
    delete dir_;
    dirs_.clear();
    valid_.clear();
  }
  static std::filesystem::path field_path() { return dir_->path() / "field.exr"; }
  // The viewer showing the field under the map turned by rotation_deg.
  static ViewState field_under_the_map(double rotation_deg) {
    ViewState state;
    state.field_file = field_path();
    state.environment = "small_source";
    state.rotation_deg = rotation_deg;
    state.window_width = 640;
    state.window_height = 480;
    return state;
  }
  static std::filesystem::path map_path() {
    return testing::source_dir() / "data" / "envmaps" / "small_source.exr";
  }

  // The map without its sources by cells, plus the sources with their shadows by the LEDs'
  // flows alone.
  static Image cpu_with_sources(const relight::SplitLighting& split) {
    Image out = relight::relight(*field_, split.weights);
    relight::FieldSources(*field_).add(split, out);
    return out;
  }
  // What `lightstage relight` gives: the same with the shadows cast by the scene's recovered
  // shape where it agrees with the LEDs (one relighter: the shape recovered once).
  static Image cpu_with_shape(const relight::SplitLighting& split) {
    static relight::MapRelighter relighter(*field_);
    Image out;
    relighter.render(split, out);
    return out;
  }
  // What the viewer's last frame was: the shape's shadows once known and traced for the
  // direction (on threads of their own), the flows' before.
  static bool by_shape(const std::string& shadows) {
    return shadows.find("the scene's shape where") != std::string::npos;
  }
  static Image cpu_as_shown(const relight::SplitLighting& split, const std::string& shadows) {
    return by_shape(shadows) ? cpu_with_shape(split) : cpu_with_sources(split);
  }
  // The whole map by LED cells, its sources not split off.
  static Image cpu_by_cells(double rotation_deg) {
    return relight::relight(
        *field_, relight::integrate_environment(*map_, dirs_, rotation_deg, 0.0, valid_));
  }
  static bool rendered(const relight::SplitLighting& split) {
    return std::any_of(split.sources.begin(), split.sources.end(),
                       [](const relight::PlacedSource& s) { return s.triangle.has_value(); });
  }

  static testing::TempDir* dir_;
  static capture::ReflectanceField* field_;
  static physics::EnvironmentMap* map_;
  static std::vector<Eigen::Vector3d> dirs_;
  static std::vector<bool> valid_;
};
testing::TempDir* ViewerBrightSources::dir_ = nullptr;
capture::ReflectanceField* ViewerBrightSources::field_ = nullptr;
physics::EnvironmentMap* ViewerBrightSources::map_ = nullptr;
std::vector<Eigen::Vector3d> ViewerBrightSources::dirs_;
std::vector<bool> ViewerBrightSources::valid_;

TEST_F(ViewerBrightSources, FieldMatchesTheCpuWithSourcesAsTheMapTurns) {
  ViewerApp app(field_under_the_map(0.0), /*visible=*/false);
  ASSERT_TRUE(app.frame());
  EXPECT_EQ(app.error_message(), "");
  int with_a_source = 0;
  // Small steps (a drag) and large ones, round the full circle. The 2-degree source (50 deg
  // elevation) is within the dome's coverage at all but 95 and 180 deg, where the image is black:
  // it carries all of the map's light.
  for (const double deg : {0.0, 2.5, 5.0, 7.5, 20.0, 95.0, 180.0, 250.0, 300.0, 318.5, 345.0}) {
    app.apply(rotate_to(deg));
    app.frame();
    const relight::SplitLighting split =
        relight::split_lighting(*map_, field_->lights(), deg, 0.0, /*split=*/true);
    ASSERT_FALSE(split.sources.empty()) << "small_source.exr has no bright source";
    ASSERT_TRUE(app.lighting().split.has_value()) << "at " << deg << " deg";
    EXPECT_EQ(app.lighting().split->report(), split.report());
    const Image shown = app.relit_image();
    const double error = max_relative_difference(shown, cpu_as_shown(split, app.source_shadows()));
    std::cout << deg << " deg: " << split.report() << "\n  viewer vs CPU with sources: max "
              << error << " of the peak";
    // The same code on the CPU (llvmpipe): measured 0. A hardware GPU sums in another order.
    EXPECT_LT(error, 1e-5) << "at " << deg << " deg";
    if (rendered(split)) {
      ++with_a_source;
      const double from_cells = max_relative_difference(shown, cpu_by_cells(deg));
      std::cout << "; vs by cells: " << from_cells;
      // The source's light moves from the LEDs' directions to its own: its shading and shadows.
      EXPECT_GT(from_cells, 0.02) << "at " << deg << " deg";
    }
    std::cout << "\n";
  }
  EXPECT_GE(with_a_source, 8);

  // Relative steps, as a drag on the image gives (345 deg on, through 0).
  for (int step = 0; step < 16; ++step) {
    Action by = rotate_to(1.25);
    by.relative = true;
    app.apply(by);
    app.frame();
    const double deg = app.state().rotation_deg;
    const relight::SplitLighting split =
        relight::split_lighting(*map_, field_->lights(), deg, 0.0, /*split=*/true);
    const Image shown = app.relit_image();
    EXPECT_LT(max_relative_difference(shown, cpu_as_shown(split, app.source_shadows())), 1e-5)
        << "at " << deg << " deg";
  }
}

// Once the scene's shape is recovered (on a thread of its own, the frames meanwhile by the flows)
// and traced for the source's direction (on another), the viewer shows the image `lightstage
// relight` makes: the source's shadows cast by the shape where it agrees with the LEDs. A new
// direction is shown by the flows until it is traced, then by the shape again.
TEST_F(ViewerBrightSources, OnceTheShapeIsKnownTheFieldIsRelitAsLightstageRelightDoes) {
  ViewerApp app(field_under_the_map(20.0), /*visible=*/false);
  const auto frames_until_the_shape = [&] {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(2);
    while (!by_shape(app.source_shadows()) && std::chrono::steady_clock::now() < give_up) {
      app.frame();
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  };
  ASSERT_TRUE(app.frame());
  EXPECT_NE(app.source_shadows().find("the LEDs' flows while the scene's shape is recovered"),
            std::string::npos)
      << app.source_shadows();
  frames_until_the_shape();
  for (const double deg : {20.0, 21.25}) {
    const relight::SplitLighting split =
        relight::split_lighting(*map_, field_->lights(), deg, 0.0, /*split=*/true);
    ASSERT_TRUE(rendered(split));
    ASSERT_TRUE(by_shape(app.source_shadows())) << app.source_shadows();
    const Image shown = app.relit_image();
    const Image expected = cpu_with_shape(split);
    EXPECT_LT(max_relative_difference(shown, expected), 1e-5) << deg << " deg";
    // The shape moves the shadows from where the flows put them.
    const double from_flows = max_relative_difference(cpu_with_sources(split), expected);
    std::cout << deg << " deg: " << app.source_shadows() << "; shape vs flows: max " << from_flows
              << " of the peak\n";
    EXPECT_GT(from_flows, 1e-3) << deg << " deg";
    // Turned to a direction not traced yet: the flows' frame at once, the shape's soon after.
    app.apply(rotate_to(21.25));
    app.frame();
    if (deg == 20.0) {
      EXPECT_NE(app.source_shadows().find("traced for this direction"), std::string::npos)
          << app.source_shadows();
      const Image turned = app.relit_image();  // Rendered again: maybe traced by now.
      EXPECT_LT(max_relative_difference(turned,
                                        cpu_as_shown(*app.lighting().split, app.source_shadows())),
                1e-5);
    }
    frames_until_the_shape();
  }
}

// The PCA on the CPU renders the sources as the field does, from its own reconstruction (its
// LEDs' images and the normals of the reconstructed field), also when shown beside the field.
TEST_F(ViewerBrightSources, PcaOnTheCpuRendersTheSourcesFromItsReconstruction) {
  ViewState state;
  state.field_file = field_path();
  state.environment = "small_source";
  state.rotation_deg = 300;
  state.source = Source::kPca;
  state.rank = 8;
  state.split = Source::kField;
  state.window_width = 640;
  state.window_height = 480;
  ViewerApp app(state, /*visible=*/false);
  ASSERT_TRUE(app.frame());
  EXPECT_EQ(app.error_message(), "");
  ASSERT_TRUE(app.lighting().split.has_value());
  const std::vector<float> whole =
      relight::integrate_environment(*map_, dirs_, 300, 0.0, valid_).irradiance_rgb;
  EXPECT_NE(app.lighting().field_irradiance_rgb(), whole);
  relight::PcaOptions options;
  options.rank = 8;
  const relight::PcaField pca = relight::PcaField::build(*field_, options);
  // The map without its source from the PCA, plus the source from the PCA's own reconstruction.
  Image expected;
  pca.relight_led_weights_into(app.lighting().field_irradiance_rgb().data(), expected);
  BrightSourceLight from_pca(pca);
  from_pca.add(app.lighting(), expected);
  const Image shown = app.relit_image();
  EXPECT_LT(max_relative_difference(shown, expected), 1e-5);
  // Far from the map without its source (which would drop the sun).
  Image without_sun;
  pca.relight_led_weights_into(app.lighting().field_irradiance_rgb().data(), without_sun);
  EXPECT_GT(max_relative_difference(without_sun, shown), 0.5);
}

// The shader path (a hardware GPU): the sources' image computed on the CPU and added in the field
// shader.
TEST_F(ViewerBrightSources, GpuFieldAddsTheSources) {
  const GlWindow window(64, 64, "viewer_sources_test", false);
  const auto source = upload_field(*field_, std::size_t(1) << 30, FieldPrecision::kFloat);
  EXPECT_TRUE(source->adds_bright_sources());
  // Over the budget the field is shown as PCA, which keeps the whole map (the viewer then makes
  // its weights).
  EXPECT_FALSE(upload_field(*field_, 300000)->adds_bright_sources());
  EnvironmentNeeds needs;
  needs.field_sources = true;
  needs.model_lights = false;
  for (const double deg : {0.0, 1.0, 300.0}) {
    const ViewLighting lighting = environment_lighting(*map_, deg, field_->lights(), needs);
    ASSERT_TRUE(lighting.split.has_value());
    ASSERT_TRUE(renders_bright_sources(lighting)) << "at " << deg << " deg";
    GpuTarget target(source->width(), source->height());
    source->render(lighting, target);
    const double error = max_relative_difference(target.read_back(),
                                                 cpu_as_shown(*lighting.split, source->shadows()));
    std::cout << deg << " deg: GPU field vs CPU with sources: max " << error << " of the peak\n";
    EXPECT_LT(error, 1e-5);  // Float storage; only the summation order differs.
  }
  // A map without a bright source: no split, the shader adds nothing.
  const physics::EnvironmentMap studio = physics::EnvironmentMap::load(
      testing::source_dir() / "data" / "envmaps" / "softbox_studio.exr");
  const ViewLighting plain = environment_lighting(studio, 30, field_->lights(), needs);
  EXPECT_FALSE(plain.split.has_value());
  GpuTarget target(source->width(), source->height());
  source->render(plain, target);
  EXPECT_LT(max_relative_difference(target.read_back(),
                                    relight::relight(*field_, relight::integrate_environment(
                                                                  studio, dirs_, 30, 0.0, valid_))),
            1e-5);
}

}  // namespace
}  // namespace ls::viewer
