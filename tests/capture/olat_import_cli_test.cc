// `lightstage import` end to end: a real RTI set, a bad .lp refused with exit 2, a time-lapse of
// sets with their times.
#include <OpenImageIO/imageio.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "capture/field_file.h"
#include "capture/olat_import.h"
#include "tests/capture/olat_import_sets.h"

namespace ls::capture {
namespace {

using namespace olat_testing;  // NOLINT(google-build-using-namespace)

// --- CLI
// ------------------------------------------------------------------------------------------

TEST(OlatImport, CliImportsRealSetAndRejectsBadLpWithExitTwo) {
  if (!fs::exists(real_lp())) GTEST_SKIP() << real_lp() << " is absent";
  ls::testing::TempDir tmp;
  std::string output;
  const std::string cli = ls::testing::cli_path().string();
  int rc = ls::testing::run_command(cli + " import '" + real_lp().string() + "' --quiet --out '" +
                                        (tmp / "lion.exr").string() + "'",
                                    &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_NE(output.find("RTI .lp file"), std::string::npos) << output;
  EXPECT_NE(output.find("240 images"), std::string::npos) << output;
  EXPECT_NE(output.find("sRGB curve"), std::string::npos) << output;
  const ReflectanceField field = read_field(tmp / "lion.exr");
  EXPECT_EQ(field.num_lights(), 240);
  EXPECT_EQ(field.width(), 64);
  EXPECT_EQ(field.height(), 43);
  EXPECT_TRUE(fs::exists(tmp / "lion.preview.png"));
  // The options record the curve undone (the .lp default, sRGB), and no gamma beside it.
  const auto in = OIIO::ImageInput::open((tmp / "lion.exr").string());
  ASSERT_TRUE(in);
  const std::string recorded = in->spec().get_string_attribute("lightstage:options");
  EXPECT_NE(recorded.find("\"transfer\":\"srgb\""), std::string::npos) << recorded;
  EXPECT_EQ(recorded.find("gamma"), std::string::npos) << recorded;

  write_text(tmp / "bad.lp", "2\nnothing.jpg 0 0 1\n");
  // stdout to /dev/null: what comes back is stderr only.
  rc = ls::testing::run_command("{ " + cli + " import '" + (tmp / "bad.lp").string() + "' --out '" +
                                    (tmp / "bad.exr").string() + "' 2>&1 >/dev/null; }",
                                &output);
  EXPECT_EQ(rc, 2) << output;
  EXPECT_NE(output.find("bad.lp:1: count"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(tmp / "bad.exr"));
}

TEST(OlatImport, CliImportsATimeLapseWithItsTimesInOneCommand) {
  ls::testing::TempDir tmp;
  const SimSet set = render_sphere(12, 20);
  for (const char* step : {"a_morning", "b_noon", "c_evening"}) {
    write_lp(set, tmp / "series" / step, ".png", 16, [](double v) { return v; });
  }
  const std::string cli = ls::testing::cli_path().string();
  std::string output;
  // One set with its time.
  int rc = ls::testing::run_command(cli + " import '" + (tmp / "series" / "b_noon").string() +
                                        "' --time 3600 --quiet --out '" +
                                        (tmp / "one.exr").string() + "'",
                                    &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_EQ(read_field(tmp / "one.exr").scene_time_s, 3600.0);
  // The folder of steps, a time each: field_t000.exr ... in the steps' name order.
  rc = ls::testing::run_command(cli + " import '" + (tmp / "series").string() +
                                    "' --time 0 3600 7200.5 --quiet --out '" +
                                    (tmp / "fields").string() + "'",
                                &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_NE(output.find("wrote 3 time steps"), std::string::npos) << output;
  const double expected[3] = {0, 3600, 7200.5};
  for (int i = 0; i < 3; ++i) {
    const fs::path field = tmp / "fields" / ("field_t00" + std::to_string(i) + ".exr");
    EXPECT_EQ(read_field(field).scene_time_s, expected[i]) << field;
  }
  // Or an interval; a count of times that does not match is refused before anything is written.
  rc = ls::testing::run_command(cli + " import '" + (tmp / "series").string() +
                                    "' --interval 60 --quiet --out '" + (tmp / "spaced").string() +
                                    "'",
                                &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_EQ(read_field(tmp / "spaced" / "field_t002.exr").scene_time_s, 120.0);
  rc = ls::testing::run_command("{ " + cli + " import '" + (tmp / "series").string() +
                                    "' --time 0 60 --out '" + (tmp / "short").string() +
                                    "' 2>&1 >/dev/null; }",
                                &output);
  EXPECT_EQ(rc, 2) << output;
  EXPECT_NE(output.find("--time: expected one time per set (3 sets), got 2"), std::string::npos)
      << output;
  EXPECT_FALSE(fs::exists(tmp / "short"));
  // A step with other lights than the others is not a time step of the same scene: refused naming
  // it, and the steps already written are removed.
  write_lp(render_sphere(12, 16), tmp / "series" / "d_night", ".png", 16,
           [](double v) { return v; });
  rc = ls::testing::run_command("{ " + cli + " import '" + (tmp / "series").string() +
                                    "' --interval 60 --out '" + (tmp / "mixed").string() +
                                    "' 2>&1 >/dev/null; }",
                                &output);
  EXPECT_EQ(rc, 2) << output;
  EXPECT_NE(output.find("d_night: expected a set like"), std::string::npos) << output;
  EXPECT_NE(output.find("(12x12, 20 images: the time steps of one scene), got 12x12, 16 images"),
            std::string::npos)
      << output;
  EXPECT_FALSE(fs::exists(tmp / "mixed"));
}

}  // namespace
}  // namespace ls::capture
