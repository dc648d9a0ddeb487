#include "lightstage/hardware/backends.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "lightstage/errors.h"
#include "tests/lightstage/hardware/hardware_stage.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

std::string HardwareErrorText(const std::function<void()>& f) {
  try {
    f();
  } catch (const HardwareError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected HardwareError";
  return {};
}

TEST(Backends, LedsAreOpenedFirstAndAMissingChipNamesTheLed) {
  const Stage stage = testing::FakeAravisStage();
  const std::string what = HardwareErrorText([&] { (void)open_hardware(stage); });
  EXPECT_NE(
      what.find("LED " + std::to_string(stage.leds[0].id) + " (gpiochip-lightstage-absent line 0"),
      std::string::npos)
      << what;
}

TEST(Backends, SimOrUnknownBackendIsAnInputError) {
  Stage stage = testing::FakeAravisStage();
  stage.camera.backend = "sim";
  EXPECT_THROW((void)open_hardware(stage), InputError);
  EXPECT_FALSE(is_hardware_backend("sim"));
  EXPECT_TRUE(is_hardware_backend("aravis"));
  EXPECT_TRUE(is_hardware_backend("v4l2"));
}

TEST(Backends, AravisCameraThroughTheFactory) {
  const Stage stage = testing::FakeAravisStage();
  const auto camera = open_camera(stage.camera, stage.source);
  EXPECT_EQ(camera->info().id, "Fake_1");
  EXPECT_EQ(camera->info().bit_depth, 8);
}

TEST(Backends, MissingV4l2DeviceIsAHardwareErrorNamingIt) {
  CameraSpec spec;
  spec.backend = "v4l2";
  spec.device_id = "/dev/video0";
  spec.bit_depth = 8;
  if (std::filesystem::exists(spec.device_id)) GTEST_SKIP() << "this machine has /dev/video0";
  const std::string what = HardwareErrorText([&] { (void)open_camera(spec, "s.json"); });
  EXPECT_NE(what.find("/dev/video0"), std::string::npos) << what;
  spec.device_id = "7";  // An index means /dev/video7.
  if (!std::filesystem::exists("/dev/video7")) {
    EXPECT_NE(HardwareErrorText([&] { (void)open_camera(spec, "s.json"); }).find("/dev/video7"),
              std::string::npos);
  }
}

TEST(Backends, V4l2RefusesWhatAWebcamCannotDeliver) {
  CameraSpec spec;
  spec.backend = "v4l2";
  spec.device_id = "/dev/video0";
  spec.bit_depth = 12;
  try {
    (void)open_camera(spec, "s.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("s.json: camera.bit_depth"), std::string::npos)
        << e.what();
  }
}

TEST(Backends, ListingWithoutCamerasSendsNothingAndNeverThrows) {
  const DeviceList list = list_devices(/*list_aravis=*/false);
  EXPECT_TRUE(list.aravis_cameras.empty());
}

// The CLI refuses to start on hardware it cannot open, before any frame.
class CliHardware : public ::testing::Test {
 protected:
  void SetUp() override {
    std::ofstream(tmp_ / "stage.json") << stage_to_json(testing::FakeAravisStage());
  }
  testing::TempDir tmp_;
};

TEST_F(CliHardware, CheckReportsTheMissingGpioChip) {
  std::string out;
  const int code = testing::run_command(
      testing::cli_path().string() + " check " + (tmp_ / "stage.json").string(), &out);
  EXPECT_EQ(code, 3) << out;
  EXPECT_NE(out.find("gpiochip-lightstage-absent"), std::string::npos) << out;
}

TEST_F(CliHardware, CaptureStopsBeforeAnythingIsCaptured) {
  std::string out;
  const int code = testing::run_command(testing::cli_path().string() + " capture --quiet --stage " +
                                            (tmp_ / "stage.json").string() + " --out " +
                                            (tmp_ / "session").string(),
                                        &out);
  EXPECT_EQ(code, 3) << out;
  EXPECT_NE(out.find("hardware error"), std::string::npos) << out;
  EXPECT_FALSE(std::filesystem::exists(tmp_ / "session" / "frames")) << out;
}

TEST_F(CliHardware, DevicesWithoutCameraDiscovery) {
  std::string out;
  const int code =
      testing::run_command(testing::cli_path().string() + " devices --no-cameras", &out);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("GPIO chips"), std::string::npos) << out;
}

}  // namespace
}  // namespace ls
