// A DSLR through the gphoto2 back-end's camera logic, over the simulated DSLR (a tether that
// behaves as libgphoto2 shows a camera: settings with choices, files as events, busy, lost files,
// a camera that vanishes); and the real libgphoto2 where no camera is attached.
#include "lightstage/hardware/tethered_camera.h"

#include <gtest/gtest.h>

#include <memory>

#include "lightstage/errors.h"
#include "lightstage/hardware/backends.h"
#include "lightstage/raw_photo.h"
#include "sim/dslr_backend.h"
#include "sim/scene.h"
#include "tests/lightstage/hardware/hardware_stage.h"

namespace ls {
namespace {

Stage dslr_stage() {
  Stage stage = stage_with_directions(fibonacci_dome_directions(6, 10));
  stage.source = "dslr.json";
  stage.camera.backend = "sim-dslr";
  stage.camera.width = stage.camera.height = 32;
  stage.camera.bit_depth = 16;
  stage.camera.timeout_s = 0.3;
  stage.camera.tether.settings = {{"f-number", "f/11"}};
  return stage;
}

using testing::error_of;

TEST(TetheredCamera, ShootsAtTheCamerasNearestChoiceAndReportsWhatItShot) {
  const Stage stage = dslr_stage();
  const auto dome = sim::open_simulated_dslr_dome(stage, sim::default_scene(), 1);
  dome->lights->set_light(0, true);
  FrameRequest request;
  request.exposure_s = 0.016;  // Between 1/60 (0.0167) and 1/80: 1/60 is nearer.
  request.gain = 2.1;          // ISO 210: 200 is the nearest third stop.
  const CapturedFrame frame = dome->camera->capture(request);
  EXPECT_NEAR(frame.exposure_s, 1.0 / 60, 1e-12);
  EXPECT_NEAR(frame.gain, 2.0, 1e-12);
  EXPECT_EQ(frame.raw.width, 32);
  EXPECT_EQ(frame.raw.channels, 3);
  EXPECT_EQ(frame.raw.bit_depth, 16);
  EXPECT_EQ(frame.original_name, "IMG_0001.DNG");
  EXPECT_FALSE(frame.original_file.empty());
  // The file kept is the camera's own: it decodes to the frame handed on.
  const DecodedRaw again = decode_raw_photo(frame.original_file, "kept.dng");
  EXPECT_EQ(again.frame.pixels, frame.raw.pixels);
  EXPECT_NEAR(again.exposure_s, 1.0 / 60, 1e-6);
  // Downloaded, then deleted from the card (camera.gphoto2.delete_from_camera).
  EXPECT_EQ(dome->dslr->files_on_card(), 0u);
  const auto settings = dome->camera->reported_settings();
  EXPECT_EQ(settings.front(), (std::pair<std::string, std::string>{"f-number", "f/11"}));
  EXPECT_EQ(settings.at(1), (std::pair<std::string, std::string>{"imageformat", "RAW"}));
}

TEST(TetheredCamera, ASettingTheCameraLacksOrRefusesNamesTheStageField) {
  Stage stage = dslr_stage();
  stage.camera.tether.settings = {{"whitebalance", "Daylight"}};
  EXPECT_NE(error_of<HardwareError>(
                [&] { (void)sim::open_simulated_dslr_dome(stage, sim::default_scene(), 1); })
                .find("dslr.json: camera.gphoto2.settings.whitebalance: camera lightstage "
                      "simulated DSLR (sim:usb) has no such setting"),
            std::string::npos);
  stage.camera.tether.settings = {{"f-number", "f/2"}};
  const std::string what = error_of<HardwareError>(
      [&] { (void)sim::open_simulated_dslr_dome(stage, sim::default_scene(), 1); });
  EXPECT_NE(what.find("offers \"f/4\", \"f/5.6\", \"f/8\", \"f/11\", \"f/16\", not \"f/2\""),
            std::string::npos)
      << what;
  stage.camera.tether.settings = {};
  stage.camera.tether.shutter_setting = "exposuretime";
  EXPECT_NE(error_of<HardwareError>([&] {
              (void)sim::open_simulated_dslr_dome(stage, sim::default_scene(), 1);
            }).find("camera.gphoto2.shutter_setting"),
            std::string::npos);
}

TEST(TetheredCamera, ABusyCameraIsWaitedForWithinTheFramesTime) {
  const auto dome = sim::open_simulated_dslr_dome(dslr_stage(), sim::default_scene(), 1);
  dome->dslr->busy_for_triggers(3);
  EXPECT_NO_THROW((void)dome->camera->capture(FrameRequest{}));
  dome->dslr->busy_for_triggers(1000000);
  EXPECT_NE(error_of<CameraTimeout>([&] {
              (void)dome->camera->capture(FrameRequest{});
            }).find("busy for"),
            std::string::npos);
}

TEST(TetheredCamera, AFileThatNeverComesIsATimeout) {
  const auto dome = sim::open_simulated_dslr_dome(dslr_stage(), sim::default_scene(), 1);
  dome->dslr->lose_file_of_shot(1);
  const std::string what =
      error_of<CameraTimeout>([&] { (void)dome->camera->capture(FrameRequest{}); });
  EXPECT_NE(what.find("no raw file within"), std::string::npos) << what;
  EXPECT_NO_THROW((void)dome->camera->capture(FrameRequest{}));  // The next shot comes.
}

TEST(TetheredCamera, ACameraGoneMidSessionNamesItself) {
  const auto dome = sim::open_simulated_dslr_dome(dslr_stage(), sim::default_scene(), 1);
  dome->dslr->disconnect_after_shots(1);
  EXPECT_NO_THROW((void)dome->camera->capture(FrameRequest{}));
  const std::string what =
      error_of<HardwareError>([&] { (void)dome->camera->capture(FrameRequest{}); });
  EXPECT_NE(what.find("lightstage simulated DSLR (sim:usb)"), std::string::npos) << what;
  EXPECT_NE(what.find("the camera is gone"), std::string::npos) << what;
}

TEST(TetheredCamera, RawPlusJpegKeepsTheRawAndAJpegCameraItsJpegs) {
  Stage stage = dslr_stage();
  stage.camera.tether.settings = {{"imageformat", "RAW + Large Fine JPEG"}};
  const auto both = sim::open_simulated_dslr_dome(stage, sim::default_scene(), 1);
  const CapturedFrame raw = both->camera->capture(FrameRequest{});
  EXPECT_EQ(raw.original_name, "IMG_0001.DNG");
  EXPECT_EQ(both->dslr->files_on_card(), 0u) << "both files downloaded and deleted";

  stage.camera.bit_depth = 8;  // A JPEG camera: its codes' curve is recovered at build.
  stage.camera.tether.settings = {{"imageformat", "Large Fine JPEG"}};
  const auto jpeg = sim::open_simulated_dslr_dome(stage, sim::default_scene(), 1);
  const CapturedFrame frame = jpeg->camera->capture(FrameRequest{});
  EXPECT_EQ(frame.original_name, "IMG_0001.JPG");
  EXPECT_EQ(frame.raw.bit_depth, 8);
  EXPECT_EQ(frame.raw.width, 32);

  stage.camera.bit_depth = 16;  // Raw wanted, but the camera writes JPEGs: said at the first shot.
  const auto wrong = sim::open_simulated_dslr_dome(stage, sim::default_scene(), 1);
  const std::string what =
      error_of<HardwareError>([&] { (void)wrong->camera->capture(FrameRequest{}); });
  EXPECT_NE(what.find("the shot wrote only IMG_0001.JPG, no raw file: set the camera's image "
                      "format to RAW"),
            std::string::npos)
      << what;
}

TEST(TetheredCamera, ShutterAndIsoChoicesReadAsCamerasWriteThem) {
  double v = 0;
  EXPECT_TRUE(parse_shutter_seconds("1/125", v));
  EXPECT_DOUBLE_EQ(v, 1.0 / 125);
  EXPECT_TRUE(parse_shutter_seconds("2.0000s", v));
  EXPECT_DOUBLE_EQ(v, 2.0);
  EXPECT_TRUE(parse_shutter_seconds("0.3", v));
  EXPECT_FALSE(parse_shutter_seconds("bulb", v));
  EXPECT_TRUE(parse_iso("ISO 400", v));
  EXPECT_DOUBLE_EQ(v, 400);
  EXPECT_FALSE(parse_iso("Auto", v));
}

// The real libgphoto2, on a machine with no camera: autodetect finds none, and the error says so
// naming the stage file's field. (Skipped where a camera is attached.)
TEST(TetheredCamera, RealLibgphoto2WithNoCameraSaysSoNamingTheStageField) {
  if (!list_gphoto2_cameras().empty()) GTEST_SKIP() << "a camera is attached";
  Stage stage = dslr_stage();
  stage.camera.backend = "gphoto2";
  const std::string what =
      error_of<HardwareError>([&] { (void)open_camera(stage.camera, stage.source); });
  EXPECT_NE(what.find("dslr.json: camera.backend: \"gphoto2\": libgphoto2 detects no camera"),
            std::string::npos)
      << what;
}

}  // namespace
}  // namespace ls
