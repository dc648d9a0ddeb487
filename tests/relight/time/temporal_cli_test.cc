// lightstage fit --time and lightstage relight --temporal --time, end to end on small fields.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "capture/field.h"
#include "capture/field_file.h"
#include "relight/time/temporal_fit.h"
#include "sim/scene.h"
#include "tests/relight/time/time_fixtures.h"
#include "tests/support/test_support.h"

namespace ls::relight {
namespace {

TEST(TemporalCli, FitOverTimeThenRelightAtAnyTime) {
  ls::testing::TempDir dir;
  Stage stage = stage_with_directions(fibonacci_dome_directions(40, -11.5));
  stage.camera.width = 16;
  stage.camera.height = 12;
  const sim::Scene scene = sim::time_varying_scene();
  const std::filesystem::path fields = dir / "fields";
  std::filesystem::create_directories(fields);
  int i = 0;
  for (const double t : {0.0, 60.0, 120.0, 240.0, 400.0, 600.0}) {
    char name[32];
    std::snprintf(name, sizeof name, "field_t%03d.exr", i);
    capture::write_field(fields / name,
                         time_testing::field_at(stage, scene, t, NoiseModel{}, 11 + i));
    ++i;
  }
  const std::string cli = ls::testing::cli_path().string();
  std::string output;
  ASSERT_EQ(ls::testing::run_command(cli + " fit --quiet --time " + fields.string() + " --out " +
                                         (dir / "temporal.exr").string(),
                                     &output),
            0)
      << output;
  EXPECT_NE(output.find("6 steps from 0.0 s to 600.0 s"), std::string::npos) << output;
  const TemporalMaps maps = read_temporal_maps(dir / "temporal.exr");
  EXPECT_EQ(maps.step_times_s.size(), 6u);
  EXPECT_GT(maps.summary.fitted, 100);

  ASSERT_EQ(ls::testing::run_command(
                cli + " relight --quiet --temporal " + (dir / "temporal.exr").string() +
                    " --time 150 --light 0.2 0.3 0.93 --out " + (dir / "at150").string(),
                &output),
            0)
      << output;
  EXPECT_TRUE(std::filesystem::exists(dir / "at150" / "light_t150s.exr"));
  EXPECT_EQ(output.find("EXTRAPOLATED"), std::string::npos) << output;
  ASSERT_EQ(ls::testing::run_command(
                cli + " relight --quiet --temporal " + (dir / "temporal.exr").string() +
                    " --time 900 --light 0.2 0.3 0.93 --out " + (dir / "at900").string(),
                &output),
            0)
      << output;
  EXPECT_NE(output.find("EXTRAPOLATED"), std::string::npos) << output;
  // Usage: --temporal without --time.
  EXPECT_EQ(
      ls::testing::run_command(cli + " relight --temporal " + (dir / "temporal.exr").string() +
                                   " --light 0 0 1 --out " + (dir / "x").string(),
                               &output),
      1);
}

}  // namespace
}  // namespace ls::relight
