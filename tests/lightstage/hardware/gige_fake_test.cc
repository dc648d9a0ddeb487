// The Aravis back-end over GigE Vision: a fake camera served in-process on 127.0.0.1, opened by IP.
// Opening over GigE may run discovery, which broadcasts on every interface, so this binary runs
// only inside a private network namespace with nothing but loopback (CMake registers it through
// `unshare -n`); anywhere else every test skips.
#include <arv.h>
#include <gtest/gtest.h>
#include <ifaddrs.h>

#include <functional>
#include <string>
#include <utility>

#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "lightstage/hardware/aravis_camera.h"
#include "tests/lightstage/controller/fake_hardware.h"
#include "tests/lightstage/hardware/hardware_stage.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

// True when this process's network namespace has no interface but loopback.
bool OnlyLoopback() {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return false;
  bool only_lo = true;
  for (ifaddrs* a = list; a != nullptr; a = a->ifa_next) {
    if (a->ifa_name == nullptr || std::string(a->ifa_name) != "lo") only_lo = false;
  }
  freeifaddrs(list);
  return only_lo;
}

class GigeFake : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!OnlyLoopback()) GTEST_SKIP() << "not in a loopback-only network namespace";
    arv_enable_interface("GigEVision");
    fake_ = arv_gv_fake_camera_new_full("127.0.0.1", "LSGIGE01", nullptr);
    ASSERT_NE(fake_, nullptr);
    ASSERT_TRUE(arv_gv_fake_camera_is_running(fake_));
    arv_fake_camera_set_trigger_frequency(arv_gv_fake_camera_get_fake_camera(fake_), 200);
  }
  void TearDown() override {
    if (fake_) g_object_unref(fake_);
  }
  ArvGvFakeCamera* fake_ = nullptr;
};

TEST_F(GigeFake, CapturesOverLoopbackWithExposureReadBack) {
  CameraSpec spec = testing::FakeAravisStage().camera;
  spec.device_id = "127.0.0.1";
  spec.width = 128;
  spec.height = 96;
  AravisCamera camera(spec);
  FrameRequest r;
  r.exposure_s = 0.003;
  int ok = 0;
  for (int i = 0; i < 5; ++i) {
    const CapturedFrame f = camera.capture(r);
    EXPECT_EQ(f.raw.width, 128);
    EXPECT_EQ(f.raw.height, 96);
    EXPECT_NEAR(f.exposure_s, 0.003, 1e-6);
    ++ok;
  }
  EXPECT_EQ(ok, 5);
}

TEST_F(GigeFake, SessionOverLoopback) {
  testing::TempDir tmp;
  Stage stage = testing::FakeAravisStage(3);
  stage.camera.device_id = "127.0.0.1";
  Session session = Session::create(tmp / "s", stage, {});
  testing::FakeLights lights(int(stage.leds.size()));
  AravisCamera camera(stage.camera);
  SequencerOptions options;
  options.verify_frames = false;  // The fake camera draws a test pattern, whatever the LEDs do.
  options.sleep = [](double) {};
  const CaptureSummary summary = run_capture(session, lights, camera, options);
  EXPECT_EQ(summary.status, CaptureSummary::Status::kComplete) << summary.message;
  EXPECT_TRUE(session.complete());
  EXPECT_EQ(lights.count_on(), 0);
}

// Calls `unplug` before the frame after the first `frames` frames.
class UnpluggingCamera : public Camera {
 public:
  UnpluggingCamera(Camera& inner, int frames, std::function<void()> unplug)
      : inner_(inner), left_(frames), unplug_(std::move(unplug)) {}
  CameraInfo info() const override { return inner_.info(); }
  CapturedFrame capture(const FrameRequest& r) override {
    if (left_-- == 0) unplug_();
    return inner_.capture(r);
  }

 private:
  Camera& inner_;
  int left_;
  std::function<void()> unplug_;
};

// A real disconnect: the GigE camera disappears mid-session; all LEDs end off, the frames taken
// are kept, and once the camera is back a resume completes the session.
TEST_F(GigeFake, CameraVanishesMidSessionThenResumeAfterItReturns) {
  testing::TempDir tmp;
  Stage stage = testing::FakeAravisStage(3);
  stage.camera.device_id = "127.0.0.1";
  stage.camera.timeout_s = 0.3;
  stage.camera.retries = 0;
  testing::FakeLights lights(int(stage.leds.size()));
  {
    Session session = Session::create(tmp / "s", stage, {});
    AravisCamera camera(stage.camera);
    UnpluggingCamera unplugging(camera, 4, [&] {
      g_object_unref(fake_);
      fake_ = nullptr;
    });
    SequencerOptions options;
    options.verify_frames = false;  // The fake camera draws a test pattern, whatever the LEDs do.
    options.sleep = [](double) {};
    // The next request changes the exposure: that command goes unanswered, which is a
    // HardwareError naming the camera (not a frame timeout, which would end as kCameraFailed).
    try {
      const CaptureSummary summary = run_capture(session, lights, unplugging, options);
      ADD_FAILURE() << "expected a HardwareError, the capture ended: " << summary.message;
    } catch (const HardwareError& e) {
      EXPECT_NE(std::string(e.what()).find("camera 127.0.0.1"), std::string::npos) << e.what();
    }
    EXPECT_EQ(lights.count_on(), 0);
    EXPECT_EQ(session.frames().size(), 4u);
    // The camera comes back (before the old handle closes: closing a handle on a vanished GigE
    // camera waits out about 10 s of command timeouts in Aravis).
    fake_ = arv_gv_fake_camera_new_full("127.0.0.1", "LSGIGE01", nullptr);
    ASSERT_NE(fake_, nullptr);
    arv_fake_camera_set_trigger_frequency(arv_gv_fake_camera_get_fake_camera(fake_), 200);
  }
  Session session = Session::open(tmp / "s");
  AravisCamera camera(stage.camera);
  SequencerOptions options;
  options.verify_frames = false;  // The fake camera draws a test pattern, whatever the LEDs do.
  options.sleep = [](double) {};
  const CaptureSummary summary = run_capture(session, lights, camera, options);
  EXPECT_EQ(summary.status, CaptureSummary::Status::kComplete) << summary.message;
  EXPECT_EQ(summary.frames_already_present, 4);
  EXPECT_TRUE(session.complete());
}

}  // namespace
}  // namespace ls
