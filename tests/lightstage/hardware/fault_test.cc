// Faults during a capture on the Aravis fake camera: the camera goes away mid-session (timeouts, or
// a lost connection); all LEDs end off, every frame taken is kept, and a resume with a reconnected
// camera completes only what is missing.
#include <gtest/gtest.h>

#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "lightstage/hardware/aravis_camera.h"
#include "tests/lightstage/controller/fake_hardware.h"
#include "tests/lightstage/hardware/hardware_stage.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

// Passes frames through until `frames_before_unplug`, then fails as an unplugged camera does.
class UnpluggableCamera : public Camera {
 public:
  enum class Failure { kTimeout, kConnectionLost };
  UnpluggableCamera(Camera& inner, int frames_before_unplug, Failure failure)
      : inner_(inner), left_(frames_before_unplug), failure_(failure) {}
  CameraInfo info() const override { return inner_.info(); }
  CapturedFrame capture(const FrameRequest& r) override {
    if (left_ <= 0) {
      if (failure_ == Failure::kTimeout) throw CameraTimeout("no frame: camera unplugged");
      throw HardwareError("camera Fake_1: control connection lost");
    }
    --left_;
    return inner_.capture(r);
  }

 private:
  Camera& inner_;
  int left_;
  Failure failure_;
};

SequencerOptions Instant() {
  SequencerOptions o;
  o.sleep = [](double) {};
  o.verify_frames = false;  // The fake camera draws a test pattern, whatever the LEDs do.
  return o;
}

std::unique_ptr<AravisCamera> OpenFake(const Stage& stage) {
  auto camera = std::make_unique<AravisCamera>(stage.camera);
  camera->set_fake_trigger_frequency(1000);
  return camera;
}

TEST(HardwareFaults, FullCaptureOnTheAravisFake) {
  testing::TempDir tmp;
  const Stage stage = testing::FakeAravisStage();
  Session session = Session::create(tmp / "s", stage, {});
  testing::FakeLights lights(int(stage.leds.size()));
  auto camera = OpenFake(stage);
  const CaptureSummary summary = run_capture(session, lights, *camera, Instant());
  EXPECT_EQ(summary.status, CaptureSummary::Status::kComplete);
  EXPECT_TRUE(session.complete());
  EXPECT_EQ(lights.count_on(), 0);
  const RawFrame f = session.load_frame({0, 2, 1, 0});
  EXPECT_EQ(f.width, 32);
  EXPECT_EQ(f.height, 24);
  const auto& rec = session.frames().at({0, 2, 1, 0});
  EXPECT_NEAR(rec.exposure_s, 0.004, 1e-7);  // The camera's read-back value is journaled.
  // The camera's own timestamp of each frame is journaled too, in the order they were taken.
  EXPECT_GT(rec.timing.sensor_ns, 0u);
  EXPECT_LT(session.frames().at({0, 2, 0, 0}).timing.sensor_ns, rec.timing.sensor_ns);
}

class Unplug : public ::testing::TestWithParam<UnpluggableCamera::Failure> {};

TEST_P(Unplug, LedsOffNothingLostResumeAfterReconnectCompletes) {
  testing::TempDir tmp;
  const Stage stage = testing::FakeAravisStage();
  const int total = int(plan_frames(stage).size());
  testing::FakeLights lights(int(stage.leds.size()));
  {
    Session session = Session::create(tmp / "s", stage, {});
    auto camera = OpenFake(stage);
    UnpluggableCamera flaky(*camera, /*frames_before_unplug=*/5, GetParam());
    if (GetParam() == UnpluggableCamera::Failure::kTimeout) {
      const CaptureSummary summary = run_capture(session, lights, flaky, Instant());
      EXPECT_EQ(summary.status, CaptureSummary::Status::kCameraFailed);
      EXPECT_EQ(summary.frames_captured, 5);
      EXPECT_NE(summary.message.find("resume"), std::string::npos) << summary.message;
    } else {
      EXPECT_THROW(run_capture(session, lights, flaky, Instant()), HardwareError);
    }
    EXPECT_EQ(lights.count_on(), 0) << "an LED was left on after the camera went away";
    EXPECT_GE(lights.all_off_calls, 2);
  }
  // Reconnect: a fresh camera, the session reopened from disk.
  Session session = Session::open(tmp / "s");
  EXPECT_EQ(int(session.frames().size()), 5);
  auto camera = OpenFake(stage);
  const CaptureSummary summary = run_capture(session, lights, *camera, Instant());
  EXPECT_EQ(summary.status, CaptureSummary::Status::kComplete);
  EXPECT_EQ(summary.frames_already_present, 5);
  EXPECT_EQ(summary.frames_captured, total - 5);
  EXPECT_TRUE(session.complete());
  EXPECT_EQ(lights.count_on(), 0);
}

INSTANTIATE_TEST_SUITE_P(CameraGoesAway, Unplug,
                         ::testing::Values(UnpluggableCamera::Failure::kTimeout,
                                           UnpluggableCamera::Failure::kConnectionLost),
                         [](const auto& info) {
                           return info.param == UnpluggableCamera::Failure::kTimeout
                                      ? std::string("Timeout")
                                      : std::string("ConnectionLost");
                         });

}  // namespace
}  // namespace ls
