// Relighting under a map through its one entry point (relight::MapRelighter) against the pieces
// it assembles: the cells of the map without its bright source, the source at its direction with
// the shadows of the scene's recovered shape; a streamed field as one in memory; the sources left
// out, with a note, over the memory given.
#include "relight/sources/map_relight.h"

#include <gtest/gtest.h>

#include <memory>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"
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

}  // namespace
}  // namespace ls
