#include "lightstage/hardware/backends.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "lightstage/errors.h"
#include "tests/lightstage/hardware/hardware_stage.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

std::string HardwareErrorText(const std::function<void()>& f) {
  return testing::error_of<HardwareError>(f);
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

// The names under /dev that start with `prefix`, sorted: an independent listing to compare with.
std::vector<std::string> DevEntries(const std::string& prefix) {
  std::vector<std::string> out;
  for (const auto& entry : std::filesystem::directory_iterator("/dev")) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) == 0) out.push_back(entry.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// `lightstage devices --no-cameras` lists what /dev holds: every /dev/video* node, and one line
// per GPIO chip naming it ("gpiochipN [label] (L lines)"), in the order of /dev.
TEST(Backends, ListingWithoutCamerasMatchesWhatDevHolds) {
  const DeviceList list = list_devices(/*list_aravis=*/false);
  EXPECT_TRUE(list.aravis_cameras.empty());  // No discovery unless asked: nothing broadcast.
  EXPECT_EQ(list.video_devices, DevEntries("video"));
  const std::vector<std::string> chips = DevEntries("gpiochip");
  bool readable = true;
  for (const std::string& c : chips) readable = readable && access(c.c_str(), R_OK) == 0;
  if (!readable) GTEST_SKIP() << "a GPIO chip under /dev is not readable: libgpiod lists none";
  ASSERT_EQ(list.gpio_chips.size(), chips.size());
  for (size_t i = 0; i < chips.size(); ++i) {
    const std::string name = std::filesystem::path(chips[i]).filename().string();
    EXPECT_EQ(list.gpio_chips[i].rfind(name + " [", 0), 0u) << list.gpio_chips[i];
    EXPECT_NE(list.gpio_chips[i].find(" lines)"), std::string::npos) << list.gpio_chips[i];
  }
}

// Stage mistakes are input errors naming the stage file and the field, raised before any device is
// opened (the chip in FakeAravisStage does not exist, so getting that far would be a
// HardwareError).
TEST(Backends, OpenHardwareInputErrorsNameTheStageField) {
  const auto input_error = [](const Stage& stage) {
    try {
      (void)open_hardware(stage);
    } catch (const InputError& e) {
      return std::string(e.what());
    } catch (const std::exception& e) {
      ADD_FAILURE() << "expected InputError, got: " << e.what();
      return std::string();
    }
    ADD_FAILURE() << "expected InputError";
    return std::string();
  };
  Stage no_chip = testing::FakeAravisStage();
  no_chip.leds[2].gpio_chip.clear();
  EXPECT_NE(input_error(no_chip).find("fake_stage.json: leds[2] (id " +
                                      std::to_string(no_chip.leds[2].id) + "): gpio_chip"),
            std::string::npos)
      << input_error(no_chip);
  Stage negative = testing::FakeAravisStage();
  negative.leds[1].gpio_line = -3;
  EXPECT_NE(input_error(negative).find("leds[1] (id " + std::to_string(negative.leds[1].id) +
                                       "): gpio_line: expected a line offset >= 0, got -3"),
            std::string::npos)
      << input_error(negative);
  Stage shared = testing::FakeAravisStage();
  shared.leds[3].gpio_line = shared.leds[0].gpio_line;
  EXPECT_NE(input_error(shared).find("leds[3] (id " + std::to_string(shared.leds[3].id) +
                                     "): gpio_line: gpiochip-lightstage-absent line 0 is already "
                                     "used by LED " +
                                     std::to_string(shared.leds[0].id)),
            std::string::npos)
      << input_error(shared);
  Stage unknown = testing::FakeAravisStage();
  unknown.camera.backend = "usb";
  EXPECT_NE(input_error(unknown).find("fake_stage.json: camera.backend"), std::string::npos)
      << input_error(unknown);
  Stage webcam = testing::FakeAravisStage();  // No GenICam I/O lines on V4L2.
  webcam.camera.backend = "v4l2";
  webcam.camera.sync.exposure_active_output = "Line1";
  EXPECT_NE(input_error(webcam).find("fake_stage.json: camera.sync: a trigger line or an "
                                     "exposure-active output needs a GenICam camera"),
            std::string::npos)
      << input_error(webcam);
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
