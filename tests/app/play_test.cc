// The map played on the simulated dome against the field relit: they agree within the
// noise for each shipped map, and an LED changed after the field was captured (20% dimmer, or
// moved 3 degrees) is found by bisecting the dome, and named.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "app/jobs/play_job.h"
#include "tests/app/e2e_fixtures.h"
#include "tests/support/test_support.h"

namespace ls::jobs {
namespace {

const std::filesystem::path kMaps =
    std::filesystem::path(LIGHTSTAGE_SOURCE_DIR) / "data" / "envmaps";

class Play : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    stage_ = new Stage(default_stage());
    stage_->camera.width = stage_->camera.height = 96;
    dir_ = new testing::TempDir;
    field_ = new capture::ReflectanceField(
        testing::CaptureAndBuild(*dir_ / "s", *stage_, sim::default_scene(), 5));
  }
  static void TearDownTestSuite() {
    delete field_;
    delete dir_;
    delete stage_;
  }

  PlayResult PlayOn(sim::SimStage& dome, const std::string& map, int audit_group_size = 0) {
    PlayOptions options;
    options.audit_group_size = audit_group_size;
    options.env_map = kMaps / map;
    options.out_dir = *dir_ / ("play_" + map);
    return play_map(*stage_, *field_, dome.lights(), dome.camera(), options);
  }

  static Stage* stage_;
  static testing::TempDir* dir_;
  static capture::ReflectanceField* field_;
};
Stage* Play::stage_ = nullptr;
testing::TempDir* Play::dir_ = nullptr;
capture::ReflectanceField* Play::field_ = nullptr;

TEST_F(Play, EachShippedMapPlayedOnTheDomeAgreesWithTheRelitField) {
  sim::SimStage dome(*stage_, sim::default_scene(), 9);
  for (const char* map : {"softbox_studio.exr", "sky_sun.exr", "small_source.exr"}) {
    const PlayResult result = PlayOn(dome, map);
    std::printf(
        "%s: PSNR %.1f dB, relative RMSE %.2f%%, chi2/N %.2f, gain %.4f, outlying %d "
        "(scale %.2f)\n",
        map, result.check.psnr_db, 100 * result.check.relative_rmse, result.check.reduced_chi2,
        result.check.gain, result.check.outlying_blocks, result.check.noise_scale);
    EXPECT_TRUE(result.agrees) << map;
    EXPECT_TRUE(result.suspects.empty()) << map;
    EXPECT_EQ(result.patterns, 1);
    // Within the noise: the brightness agrees to 0.5%.
    EXPECT_NEAR(result.check.gain, 1.0, 0.005) << map;
    EXPECT_TRUE(std::filesystem::exists(*dir_ / ("play_" + std::string(map)) / "compare.png"));
  }
}

// A bright LED of the studio map, facing the scene.
int BrightFrontLed(const Stage& stage) {
  int best = -1;
  for (int i = 0; i < int(stage.leds.size()); ++i) {
    const Eigen::Vector3d& d = stage.leds[size_t(i)].dir_in_stage;
    if (d.z() > 0.5 && d.y() > 0.3 &&
        (best < 0 || d.y() > stage.leds[size_t(best)].dir_in_stage.y())) {
      best = i;
    }
  }
  return best;
}

TEST_F(Play, AnLedDimmedByTwentyPercentIsFoundAndNamed) {
  sim::SimStage dome(*stage_, sim::default_scene(), 9);
  const int led = BrightFrontLed(*stage_);
  ASSERT_GE(led, 0);
  dome.perturb_led(led, 0.8, stage_->leds[size_t(led)].dir_in_stage);
  const PlayResult result = PlayOn(dome, "softbox_studio.exr", 8);
  ASSERT_EQ(result.suspects.size(), 1u);
  EXPECT_EQ(result.suspects[0].led_id, stage_->leds[size_t(led)].id);
  EXPECT_NEAR(result.suspects[0].check.gain, 0.8, 0.01);
  EXPECT_EQ(result.suspects[0].check.outlying_blocks, 0);  // Dimmer: the same light, less.
  std::printf("%s (%d patterns)\n", result.suspects[0].describe().c_str(), result.patterns);
}

TEST_F(Play, AnLedMovedByThreeDegreesIsFoundAndNamed) {
  sim::SimStage dome(*stage_, sim::default_scene(), 9);
  const int led = BrightFrontLed(*stage_);
  const Eigen::Vector3d dir = stage_->leds[size_t(led)].dir_in_stage;
  const Eigen::Vector3d axis = dir.cross(Eigen::Vector3d::UnitY()).normalized();
  dome.perturb_led(led, 1.0, Eigen::AngleAxisd(3 * M_PI / 180, axis) * dir);
  const PlayResult result = PlayOn(dome, "softbox_studio.exr", 8);
  ASSERT_EQ(result.suspects.size(), 1u);
  EXPECT_EQ(result.suspects[0].led_id, stage_->leds[size_t(led)].id);
  EXPECT_GE(result.suspects[0].check.outlying_blocks, 2);  // Its shading and shadows moved.
  std::printf("%s (%d patterns)\n", result.suspects[0].describe().c_str(), result.patterns);
}

TEST(PlayCommand, ChecksASessionAndWritesItsReport) {
  testing::TempDir tmp;
  const std::string cli = testing::cli_path().string();
  const std::string stage =
      (std::filesystem::path(LIGHTSTAGE_SOURCE_DIR) / "data/stages/small_dome.json").string();
  const std::string s = (tmp / "s").string(), f = (tmp / "f.exr").string();
  std::string output;
  ASSERT_EQ(
      testing::run_command(cli + " capture --quiet --stage " + stage + " --out " + s, &output), 0)
      << output;
  ASSERT_EQ(testing::run_command(cli + " build --quiet " + s + " --out " + f, &output), 0)
      << output;
  const std::string play = cli + " play " + s + " --field " + f + " --env " +
                           (kMaps / "sky_sun.exr").string() + " --out " + (tmp / "p").string();
  EXPECT_EQ(testing::run_command(play, &output), 0) << output;
  EXPECT_NE(output.find("the dome reproduces the field"), std::string::npos) << output;
  for (const char* file : {"photo.exr", "relit.exr", "compare.png", "report.json"}) {
    EXPECT_TRUE(std::filesystem::exists(tmp / "p" / file)) << file;
  }
  // A file that is no field is refused, naming it: exit 2, nothing played.
  const std::string not_a_field = (kMaps / "sky_sun.exr").string();
  EXPECT_EQ(testing::run_command(cli + " play " + s + " --field " + not_a_field + " --env " +
                                     not_a_field + " --out " + (tmp / "q").string(),
                                 &output),
            2)
      << output;
  EXPECT_NE(output.find("not a reflectance field"), std::string::npos) << output;
}

}  // namespace
}  // namespace ls::jobs
