// Relighting under a map through its one entry point (relight::MapRelighter) against the pieces
// it assembles: the cells of the map without its bright source, the source at its direction with
// the shadows of the scene's recovered shape; a streamed field as one in memory; the sources left
// out, with a note, over the memory given.
#include "relight/sources/map_relight.h"

#include <gtest/gtest.h>

#include <memory>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/stage.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "relight/sources/guided_upsample.h"
#include "sim/ground_truth.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"
#include "sim/scene.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

// A 64x48 field of a sphere casting shadows on a backdrop, under 40 LEDs, as read from its file,
// and a map with one small bright source.
class MapRelighterTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<testing::TempDir>();
    Stage stage = sim::rti_dome_stage(40, 10.0, 64);
    stage.camera.height = 48;
    capture::FieldNoise noise;
    noise.read_variance = 1e-6;
    noise.shot_variance_per_unit = 1e-5;
    capture::write_field(
        field_path(),
        sim::render_noisy_field(stage, sim::rti_scene(sim::RtiScene::kShadowed), noise, 11));
    field_ = std::make_unique<capture::ReflectanceField>(capture::read_field(field_path()));
    map_ = std::make_unique<physics::EnvironmentMap>(physics::EnvironmentMap::load(
        testing::source_dir() / "data" / "envmaps" / "small_source.exr"));
  }
  static void TearDownTestSuite() {
    map_.reset();
    field_.reset();
    dir_.reset();
  }
  static std::filesystem::path field_path() { return dir_->path() / "field.exr"; }

  static std::unique_ptr<testing::TempDir> dir_;
  static std::unique_ptr<capture::ReflectanceField> field_;
  static std::unique_ptr<physics::EnvironmentMap> map_;
};
std::unique_ptr<testing::TempDir> MapRelighterTest::dir_;
std::unique_ptr<capture::ReflectanceField> MapRelighterTest::field_;
std::unique_ptr<physics::EnvironmentMap> MapRelighterTest::map_;

TEST_F(MapRelighterTest, AFieldIsTheCellsOfTheRestPlusTheSourceCastByItsShape) {
  const double rotation = 30;
  const relight::SplitLighting split =
      relight::split_lighting(*map_, field_->lights(), rotation, 0.0, /*split=*/true);
  ASSERT_TRUE(relight::MapRelighter::renders_sources(split)) << split.report();
  Image expected = relight::relight(*field_, split.weights);
  relight::FieldSources sources(*field_);
  sources.recover_geometry();
  sources.add(split, expected);

  relight::MapRelighter relighter(*field_);
  const relight::MapRelit relit = relighter.relight(*map_, rotation);
  EXPECT_EQ(relit.lighting.report(), split.report());
  EXPECT_TRUE(relit.geometry);
  EXPECT_TRUE(relit.note.empty()) << relit.note;
  EXPECT_EQ(relit.image.pixels, expected.pixels);
}

TEST_F(MapRelighterTest, WithoutBrightSourcesTheWholeMapIsRelitByTheCells) {
  std::vector<Eigen::Vector3d> dirs;
  std::vector<bool> valid;
  for (const capture::FieldLight& light : field_->lights()) {
    dirs.push_back(light.dir_in_stage);
    valid.push_back(light.valid);
  }
  const Image expected =
      relight::relight(*field_, relight::integrate_environment(*map_, dirs, 200, 0.0, valid));
  relight::MapRelightOptions cells;
  cells.bright_sources = false;
  relight::MapRelighter relighter(*field_, cells);
  const relight::MapRelit relit = relighter.relight(*map_, 200);
  EXPECT_TRUE(relit.lighting.sources.empty());
  EXPECT_EQ(relit.image.pixels, expected.pixels);
}

// Read a few rows at a time in two ranges (as two MPI ranks would), gathered, then the sources
// from bands: the same bytes as the field in memory.
TEST_F(MapRelighterTest, AStreamedFieldGivesTheImagesOfTheFieldInMemory) {
  relight::MapRelighter in_memory(*field_);
  capture::FieldStream stream(field_path());
  relight::MapRelighter streamed(stream);
  relight::RowPass pass;
  pass.rows = {{0, 20}, {20, 48}};
  int gathered = 0;
  pass.gather = [&](const std::vector<Image*>& images) {
    gathered = int(images.size());
    return true;
  };
  const relight::MapRelitSet set =
      streamed.relight_all({{map_.get(), 0.0}, {map_.get(), 120.0}}, pass);
  ASSERT_TRUE(set.complete);
  EXPECT_EQ(gathered, 2);
  ASSERT_EQ(set.relit.size(), 2u);
  for (const auto& [i, rotation] : {std::pair{0, 0.0}, std::pair{1, 120.0}}) {
    const relight::MapRelit expected = in_memory.relight(*map_, rotation);
    EXPECT_EQ(set.relit[size_t(i)].lighting.report(), expected.lighting.report());
    EXPECT_TRUE(set.relit[size_t(i)].geometry);
    EXPECT_EQ(set.relit[size_t(i)].image.pixels, expected.image.pixels) << rotation << " deg";
  }
  // A process the gathering stops has its own rows only and adds no sources.
  pass.gather = [](const std::vector<Image*>&) { return false; };
  EXPECT_FALSE(streamed.relight_all({{map_.get(), 0.0}}, pass).complete);
}

// Over the memory given, first the shape is left out (the shadows by the flows alone), then the
// sources themselves (the whole map by the cells); each time the note says so.
TEST_F(MapRelighterTest, OverTheMemoryGivenTheShapeThenTheSourcesAreLeftOutWithANote) {
  relight::MapRelightOptions options;
  const relight::SplitLighting split = relight::MapRelighter(*field_).lighting(*map_, 0.0);
  int triangles = 0;
  for (const relight::PlacedSource& source : split.sources) {
    triangles += source.triangle.has_value();
  }
  const int leds = int(split.leds().size());
  options.memory_bytes =
      relight::FieldSources::bytes_needed(field_->width(), field_->height(), leds, triangles);
  ASSERT_LT(options.memory_bytes,
            relight::FieldSources::bytes_needed(field_->width(), field_->height(), leds, triangles,
                                                field_->num_lights()));
  const std::vector<relight::MapRotation> maps{{map_.get(), 0.0}};
  relight::MapRelighter no_shape(*field_, options);
  const relight::MapRelit flows = no_shape.relight_all(maps).relit.at(0);
  EXPECT_NE(flows.note.find("by the LEDs' flows alone"), std::string::npos) << flows.note;
  EXPECT_FALSE(flows.geometry);
  relight::MapRelightOptions flows_alone;
  flows_alone.source_geometry = false;
  EXPECT_EQ(flows.image.pixels,
            relight::MapRelighter(*field_, flows_alone).relight(*map_, 0.0).image.pixels);

  options.memory_bytes = 1000;
  relight::MapRelighter tight(*field_, options);
  const relight::MapRelit cells = tight.relight_all(maps).relit.at(0);
  EXPECT_NE(cells.note.find("relit by the LED cells"), std::string::npos) << cells.note;
  EXPECT_TRUE(cells.lighting.sources.empty());
  relight::MapRelightOptions no_sources;
  no_sources.bright_sources = false;
  EXPECT_EQ(cells.image.pixels,
            relight::MapRelighter(*field_, no_sources).relight(*map_, 0.0).image.pixels);
}

TEST_F(MapRelighterTest, RefusesOptionsThatMakeNoSense) {
  relight::MapRelightOptions options;
  options.split.max_radius_deg = -1;
  EXPECT_THROW(relight::MapRelighter(*field_, options), InputError);
}

// A field of more pixels than MapRelightOptions::source_pixels has its sources made on the field
// reduced, brought back to its size by the detail of the LEDs around them. The demo scene (its
// checkered plane, the relief's shadows, glossy spheres) at 192^2 on the built-in dome, streamed,
// against the ground truth of a map with a sun and one with a 2-degree lamp, sources made at 96^2.
// Measured (relative RMSE, full size / reduced / cells alone): sky_sun 0.0390 / 0.0414 / 0.117,
// small_source 0.0460 / 0.0697 / 0.184: the lamp's sharp shadows and highlight lose most to the
// block size (at 384^2 reduced to 192^2: 0.062 / 0.084). Asserted: the sun within 15% of the full
// size, the lamp as measured with a 15% margin, both at most half the cells' error.
TEST(MapRelighterReduced, SourcesMadeOnAReducedFieldKeepMostOfTheAccuracyOfTheFullSize) {
  constexpr int kSize = 192;
  Stage stage = default_stage();
  stage.camera.width = stage.camera.height = kSize;
  const sim::Scene scene = sim::default_scene();
  capture::FieldNoise noise;
  noise.read_variance = 1e-6;
  noise.shot_variance_per_unit = 1e-5;
  const testing::TempDir dir;
  const std::filesystem::path path = dir.path() / "field.exr";
  capture::write_field(path, sim::render_noisy_field(stage, scene, noise, 3));
  const auto envmap = [](const char* name) {
    return physics::EnvironmentMap::load(testing::source_dir() / "data" / "envmaps" / name);
  };
  const physics::EnvironmentMap sun = envmap("sky_sun.exr"), lamp = envmap("small_source.exr");
  const auto relit_at = [&](std::size_t source_pixels, bool sources) {
    capture::FieldStream stream(path);
    relight::MapRelightOptions options;
    options.source_pixels = source_pixels;
    options.bright_sources = sources;
    return relight::MapRelighter(stream, options).relight_all({{&sun, 0.0}, {&lamp, 0.0}}).relit;
  };
  const std::vector<relight::MapRelit> full = relit_at(0, true), cells = relit_at(0, false),
                                       reduced = relit_at(kSize * kSize / 4, true);
  const auto dirs = stage.led_directions();
  sim::GroundTruthOptions gt;
  gt.directions_width = 128;
  gt.covered_by_leds = dirs;
  gt.coverage_radius_rad = max_nearest_neighbour_angle(dirs);
  const std::array<double, 2> reduced_bound_over_full{1.15, 0.0697 * 1.15 / 0.0460};
  for (const int m : {0, 1}) {
    const Image truth = sim::render_ground_truth(scene, stage.camera, m == 0 ? sun : lamp, gt);
    const auto error = [&](const std::vector<relight::MapRelit>& relit) {
      return testing::compare_images(relit[size_t(m)].image, truth).relative_rmse;
    };
    const double at_full = error(full), at_reduced = error(reduced), by_cells = error(cells);
    std::cout << (m == 0 ? "sky_sun" : "small_source") << ": relative RMSE, sources at 192^2 "
              << at_full << ", at 96^2 " << at_reduced << "; by the cells " << by_cells << "\n";
    EXPECT_LT(at_reduced, reduced_bound_over_full[size_t(m)] * at_full) << m;
    EXPECT_LT(at_reduced, 0.5 * by_cells) << m;
  }
}

// Where the image made on the reduced field is the guide's times a constant, the upsampled image
// is the full-size guide's times it: the detail comes from the guide. Every block of the guide has
// the same mean m (its texture sums to zero in each), so the interpolated guide is m everywhere
// and the dark floor e = 3% of m gives out - before = 2.5 m (g + e) / (m + e) exactly.
TEST(GuidedUpsample, AnImageProportionalToTheGuideTakesAllOfItsDetail) {
  constexpr int kFactor = 3;
  const std::array<float, 3> mean{0.5f, 1.0f, 2.0f};
  Image guide(12, 9, 3), guide_low(4, 3, 3), low(4, 3, 3);
  for (int y = 0; y < guide.height; ++y) {
    for (int x = 0; x < guide.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float texture = float(x % kFactor - 1) * (1.0f + 0.2f * float(y % kFactor - 1));
        guide.at(x, y, c) = mean[size_t(c)] * (1.0f + 0.5f * texture);
        guide_low.at(x / kFactor, y / kFactor, c) = mean[size_t(c)];
        low.at(x / kFactor, y / kFactor, c) = 2.5f * mean[size_t(c)];
      }
    }
  }
  Image out(12, 9, 3, 1.0f);
  relight::add_guided_upsample(low, guide_low, guide, kFactor, out);
  for (int y = 0; y < guide.height; ++y) {
    for (int x = 0; x < guide.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const float m = mean[size_t(c)], e = 0.03f * m;
        EXPECT_NEAR(out.at(x, y, c), 1.0f + 2.5f * m * (guide.at(x, y, c) + e) / (m + e), 1e-5f)
            << x << "," << y << "," << c;
      }
    }
  }
}

}  // namespace
}  // namespace ls
