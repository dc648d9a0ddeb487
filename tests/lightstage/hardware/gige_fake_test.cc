// The Aravis back-end over GigE Vision: a fake camera served in-process on 127.0.0.1, opened by IP.
// Opening over GigE may run discovery, which broadcasts on every interface, so this binary runs
// only inside a private network namespace with nothing but loopback (CMake registers it through
// `unshare -n`); anywhere else every test skips.
#include <arv.h>
#include <gtest/gtest.h>
#include <ifaddrs.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "capture/reference_drift.h"
#include "capture/response.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "lightstage/hardware/aravis_camera.h"
#include "lightstage/hardware/gpiod_lights.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
#include "tests/lightstage/controller/fake_hardware.h"
#include "tests/lightstage/hardware/fake_line_driver.h"
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

// camera.sync.trigger "line" over GigE Vision: a whole session whose every frame waits for the
// controller's pulse. The fake has one input, Line0, that nothing can drive, and frames only on
// its trigger latch (TriggerSource Software); so the wire from the controller's trigger GPIO line
// (the fake line driver's) ends on that latch, set inside the camera as an edge on its input
// would, not by a command over the link. A wire that breaks stops the capture with every frame
// taken kept and the LEDs off; mended, a resume completes the session.
TEST_F(GigeFake, LineTriggeredSessionWaitsForEveryPulseAndABrokenWireStopsItResumably) {
  testing::TempDir tmp;
  Stage stage = testing::FakeAravisStage(3);
  for (Led& led : stage.leds) led.gpio_chip = "gpiochip0";
  stage.camera.device_id = "127.0.0.1";
  stage.camera.timeout_s = 0.5;
  stage.camera.retries = 1;
  stage.camera.sync.trigger = "line";
  stage.camera.sync.input = "Software";  // The latch, standing in for the input.
  stage.camera.sync.gpio_chip = "gpiochip0";
  stage.camera.sync.gpio_line = 9;
  testing::FakeGpio gpio;
  GpioLights lights(stage, std::make_unique<testing::FakeLineDriver>(gpio));
  ArvFakeCamera* inside = arv_gv_fake_camera_get_fake_camera(fake_);
  bool connected = true;
  std::vector<int64_t> rising_ns;
  gpio.wire = [&](const std::pair<std::string, int>& line, bool high) {
    if (line.second != 9 || !high) return;
    rising_ns.push_back(std::chrono::duration_cast<std::chrono::nanoseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count());
    if (connected)
      arv_fake_camera_write_register(inside, ARV_FAKE_CAMERA_REGISTER_TRIGGER_SOFTWARE, 1);
  };
  AravisCamera camera(stage.camera);
  wire_trigger(stage.camera, lights, camera);
  SequencerOptions options;
  options.verify_frames = false;  // The fake camera draws a test pattern, whatever the LEDs do.
  options.sleep = [](double) {};
  const int broken_after = 5;
  options.on_progress = [&](const std::string&, long done, long, const std::string&) {
    connected = done < broken_after;
  };
  Session session = Session::create(tmp / "s", stage, {});
  const CaptureSummary stopped = run_capture(session, lights, camera, options);
  EXPECT_EQ(stopped.status, CaptureSummary::Status::kCameraFailed);
  EXPECT_NE(stopped.message.find("after pulsing the trigger line"), std::string::npos)
      << stopped.message;
  EXPECT_EQ(lights.count_on(), 0);
  EXPECT_EQ(session.frames().size(), size_t(broken_after));
  // One pulse a frame taken, and one for each attempt unanswered (retries included).
  EXPECT_EQ(rising_ns.size(), size_t(broken_after + 1 + stopped.camera_retries));

  connected = true;
  options.on_progress = nullptr;
  Session again = Session::open(tmp / "s");
  const CaptureSummary resumed = run_capture(again, lights, camera, options);
  EXPECT_EQ(resumed.status, CaptureSummary::Status::kComplete) << resumed.message;
  EXPECT_TRUE(again.complete());
  EXPECT_EQ(rising_ns.size(), size_t(broken_after + 1 + stopped.camera_retries) +
                                  again.frames().size() - broken_after + resumed.camera_retries);
  for (const auto& [key, record] : again.frames()) {
    // Every frame was exposed after it was asked for (its pulse) and within its LED's window.
    EXPECT_GE(int64_t(record.timing.sensor_ns), record.timing.requested_ns) << key.name(stage);
    if (key.led_index >= 0) {
      EXPECT_LE(record.timing.led_on_ns, int64_t(record.timing.sensor_ns)) << key.name(stage);
      EXPECT_LE(int64_t(record.timing.sensor_ns), record.timing.led_off_ns) << key.name(stage);
    }
  }
  gpio.wire = nullptr;
}

// Aravis' GigE Vision fake drawing the simulated stage: its fill hook renders the frame the
// simulator delivers under the LEDs the controller has on (mirrored from the fake GPIO lines), at
// the exposure the camera was set to over GigE Vision. The frame checks then see frames that
// follow the LEDs, and faults go in where a camera's frames come from, through the real protocol.
class SimulatedSceneOnTheFake {
 public:
  SimulatedSceneOnTheFake(const Stage& stage, ArvGvFakeCamera* fake, testing::FakeGpio& gpio)
      : stage_(stage),
        sim_(stage, sim::default_scene(), 11),
        fake_(arv_gv_fake_camera_get_fake_camera(fake)),
        gpio_(gpio) {
    gpio_.wire = [this](const std::pair<std::string, int>& line, bool high) {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (line.second >= int(stage_.leds.size())) return;
      sim_.lights().set_light(line.second, high);
      lit_[size_t(line.second)] = high;
    };
  }
  ~SimulatedSceneOnTheFake() {
    arv_fake_camera_set_fill_pattern(fake_, nullptr, nullptr);
    gpio_.wire = nullptr;
  }
  void start_drawing() {
    arv_fake_camera_set_fill_pattern(fake_, &SimulatedSceneOnTheFake::fill, this);
  }
  enum class Fault { kWrongLed, kTorn, kStale };
  // The next frame of LED `led` at bracket step `exposure_index` is drawn with `fault`: lit by the
  // next LED, only its top half new, or not drawn at all (the previous frame sent again).
  void fault_next(int led, int exposure_index, Fault fault) {
    const std::lock_guard<std::mutex> lock(mutex_);
    faults_[{led, exposure_index}] = fault;
  }
  void set_output_drift(double per_frame) {
    const std::lock_guard<std::mutex> lock(mutex_);
    sim_.set_output_drift(per_frame);
  }

 private:
  static void fill(ArvBuffer* buffer, void* self, guint32 exposure_us, guint32 /*gain*/,
                   ArvPixelFormat /*format*/) {
    try {  // Called from C, on the fake's thread: nothing may escape.
      static_cast<SimulatedSceneOnTheFake*>(self)->draw(buffer, exposure_us);
    } catch (const std::exception& e) {
      ADD_FAILURE() << "drawing a frame: " << e.what();
    }
  }
  void draw(ArvBuffer* buffer, guint32 exposure_us) {
    const std::lock_guard<std::mutex> lock(mutex_);
    FrameRequest request;
    request.exposure_s = exposure_us * 1e-6;
    request.sequence_key = ++frames_;
    int step = 0;
    for (size_t k = 0; k < stage_.camera.bracket.size(); ++k) {
      if (std::abs(stage_.camera.bracket[k].exposure_s - request.exposure_s) < 1e-5) step = int(k);
    }
    std::optional<Fault> fault;
    for (int led = 0; led < int(stage_.leds.size()); ++led) {
      const auto it = faults_.find({led, step});
      if (lit_[size_t(led)] && it != faults_.end()) {
        fault = it->second;
        faults_.erase(it);
      }
    }
    if (fault == Fault::kStale) return;  // The fake's buffer still holds the previous frame.
    if (fault == Fault::kWrongLed) {
      sim_.inject_frame_fault(request.sequence_key, sim::SimStage::FrameFault::kWrongLed);
    }
    const CapturedFrame frame = sim_.camera().capture(request);
    // The fake calls its pattern only with a buffer that holds a whole frame (and sends it whole).
    auto* data = static_cast<uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, nullptr)));
    // Torn: only the top half arrives new, the rest is the previous frame's.
    const size_t drawn =
        fault == Fault::kTorn ? frame.raw.pixels.size() / 2 : frame.raw.pixels.size();
    for (size_t i = 0; i < drawn; ++i) {
      data[2 * i] = uint8_t(frame.raw.pixels[i] & 0xff);  // Mono16, little-endian.
      data[2 * i + 1] = uint8_t(frame.raw.pixels[i] >> 8);
    }
  }

  Stage stage_;
  sim::SimStage sim_;
  ArvFakeCamera* fake_;
  testing::FakeGpio& gpio_;
  std::mutex mutex_;  // The hook runs on the fake's thread.
  std::vector<bool> lit_ = std::vector<bool>(stage_.leds.size(), false);
  uint64_t frames_ = 0;
  std::map<std::pair<int, int>, Fault> faults_;
};

// The stage's LEDs on fake GPIO lines, Aravis' GigE fake drawn by the simulator under them, and
// captures on them without waits.
struct SimulatedRig {
  SimulatedRig(const Stage& stage, ArvGvFakeCamera* fake)
      : lights(stage, std::make_unique<testing::FakeLineDriver>(gpio)),
        scene(stage, fake, gpio),
        camera(stage.camera) {
    scene.start_drawing();
  }
  CaptureSummary capture(Session& session) {
    SequencerOptions options;
    options.sleep = [](double) {};
    return run_capture(session, lights, camera, options);
  }
  testing::FakeGpio gpio;
  GpioLights lights;
  SimulatedSceneOnTheFake scene;
  AravisCamera camera;
};

// Six LEDs on gpiochip0 lines 0-5, all on the camera's side (60 degrees apart around the view
// axis, 40 degrees off it), a 128 x 96 16-bit camera on the GigE fake, the default bracket.
Stage SimulatedGigeStage() {
  Stage stage = testing::FakeAravisStage(6);
  for (int i = 0; i < 6; ++i) {
    const double azimuth = i * std::numbers::pi / 3, off_axis = 40 * std::numbers::pi / 180;
    stage.leds[size_t(i)].dir_in_stage = {std::sin(off_axis) * std::cos(azimuth),
                                          std::sin(off_axis) * std::sin(azimuth),
                                          std::cos(off_axis)};
    stage.leds[size_t(i)].gpio_chip = "gpiochip0";
  }
  stage.camera.device_id = "127.0.0.1";
  stage.camera.width = 128;
  stage.camera.height = 96;
  stage.camera.bit_depth = 16;
  stage.camera.bracket = stage_with_directions({Eigen::Vector3d::UnitY()}).camera.bracket;
  stage.plan.dark_frames = 2;
  return stage;
}

// Frame faults injected into the fake camera: a frame lit by the wrong LED, a torn one
// and a stale one each fail their bracket's check on arrival, are shot again and journaled, and
// the session completes with no LED judged dead; a clean capture raises no alarm.
TEST_F(GigeFake, FramesDrawnBySimulatorFaultsAreCaughtShotAgainAndJournaled) {
  testing::TempDir tmp;
  const Stage stage = SimulatedGigeStage();
  SimulatedRig rig(stage, fake_);
  Session clean = Session::create(tmp / "clean", stage, {});
  ASSERT_EQ(rig.capture(clean).status, CaptureSummary::Status::kComplete);
  EXPECT_TRUE(clean.frame_problems().empty());
  EXPECT_TRUE(clean.dead_leds().empty());

  rig.scene.fault_next(1, 2, SimulatedSceneOnTheFake::Fault::kWrongLed);
  rig.scene.fault_next(3, 1, SimulatedSceneOnTheFake::Fault::kTorn);
  rig.scene.fault_next(4, 2, SimulatedSceneOnTheFake::Fault::kStale);
  Session faulty = Session::create(tmp / "faulty", stage, {});
  const CaptureSummary summary = rig.capture(faulty);
  EXPECT_EQ(summary.status, CaptureSummary::Status::kComplete) << summary.message;
  EXPECT_EQ(summary.frames_reshot, 3);
  std::vector<FrameKey> rejected;
  for (const FrameProblem& p : faulty.frame_problems()) rejected.push_back(p.key);
  const std::vector<FrameKey> injected = {{0, 1, 2, 0}, {0, 3, 1, 0}, {0, 4, 2, 0}};
  EXPECT_EQ(rejected, injected);
  EXPECT_TRUE(faulty.dead_leds().empty());
}

// A drifting dome seen through the fake camera: the reference LED, shot again every two LEDs,
// measures the drift the simulator was told to add (within noise), and none without it.
TEST_F(GigeFake, DriftOfTheLedsIsMeasuredFromTheReferenceLedThroughTheFake) {
  testing::TempDir tmp;
  Stage stage = SimulatedGigeStage();
  stage.plan.reference_led = 2;
  stage.plan.reference_every = 2;
  SimulatedRig rig(stage, fake_);
  const capture::ResponseCurve response = capture::ResponseCurve::given_or_linear(stage.camera);
  double change[2] = {0, 0};
  for (int drifting = 0; drifting < 2; ++drifting) {
    rig.scene.set_output_drift(drifting ? 0.002 : 0.0);  // Per frame delivered.
    const std::string name = drifting ? "drifting" : "steady";
    Session session = Session::create(tmp / name, stage, {});
    ASSERT_EQ(rig.capture(session).status, CaptureSummary::Status::kComplete);
    const auto drift = capture::measure_reference_drift(session, 0, response);
    ASSERT_TRUE(drift.has_value()) << name;
    change[drifting] = drift->largest_change();
  }
  EXPECT_LT(change[0], 0.005);  // The reported threshold (0.5%): a steady dome is not flagged.
  // Six LEDs, three exposures and repeats of the reference's: the last shot comes some 30 frames
  // after the first, 6% brighter.
  EXPECT_GT(change[1], 0.03);
}

}  // namespace
}  // namespace ls
