#include "lightstage/controller/sequencer.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "tests/lightstage/controller/fake_hardware.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

using testing::FakeCamera;
using testing::FakeLights;

Stage SmallStage(int leds = 6) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(leds, 0));
  stage.camera.width = 8;
  stage.camera.height = 4;
  stage.camera.retries = 2;
  return stage;
}

SequencerOptions Instant() {
  SequencerOptions o;
  o.sleep = [](double) {};
  return o;
}

TEST(Sequencer, CapturesEveryPlannedFrameWithExactlyTheRightLedOn) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  Session session = Session::create(tmp / "s", stage, {});
  FakeLights lights(int(stage.leds.size()));
  FakeCamera camera(lights);
  const CaptureSummary summary = run_capture(session, lights, camera, Instant());
  EXPECT_EQ(summary.status, CaptureSummary::Status::kComplete);
  EXPECT_EQ(summary.frames_captured, int(plan_frames(stage).size()));
  EXPECT_TRUE(session.complete());
  EXPECT_EQ(lights.max_on, 1);  // Never two LEDs at once.
  EXPECT_EQ(lights.count_on(), 0);
  EXPECT_EQ(lights.switch_ons, int(stage.leds.size()));  // Once per LED, for its whole bracket.
  // The frame of LED 4 at the middle exposure holds LED 4's signal.
  const RawFrame f = session.load_frame({0, 4, 1, 0});
  EXPECT_EQ(f.pixels[0], 50 + 140);
  EXPECT_EQ(session.load_frame({0, -1, 1, 1}).pixels[0], 50);
  EXPECT_TRUE(session.dead_leds().empty());
}

TEST(Sequencer, EachFrameIsJournaledWithWhenItsLedWasOnAndWhenItWasTaken) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  {
    Session session = Session::create(tmp / "s", stage, {});
    FakeLights lights(int(stage.leds.size()));
    FakeCamera camera(lights);
    ASSERT_EQ(run_capture(session, lights, camera, Instant()).status,
              CaptureSummary::Status::kComplete);
  }
  const Session session = Session::open(tmp / "s");  // As journaled.
  for (const auto& [key, record] : session.frames()) {
    const FrameTiming& t = record.timing;
    EXPECT_GT(t.requested_ns, 0) << key.name(stage);
    EXPECT_LE(t.requested_ns, t.delivered_ns) << key.name(stage);
    if (key.is_dark()) {
      EXPECT_EQ(t.led_on_ns, 0) << key.name(stage);
      continue;
    }
    // A lit frame was asked for and received while its LED was on.
    EXPECT_GT(t.led_on_ns, 0) << key.name(stage);
    EXPECT_LE(t.led_on_ns, t.requested_ns) << key.name(stage);
    EXPECT_LE(t.delivered_ns, t.led_off_ns) << key.name(stage);
  }
}

TEST(Sequencer, StopRequestLeavesLedsOffAndResumeCompletesOnlyWhatIsMissing) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  Session session = Session::create(tmp / "s", stage, {});
  FakeLights lights(int(stage.leds.size()));
  FakeCamera camera(lights);
  std::atomic<bool> stop{false};
  SequencerOptions options = Instant();
  options.stop_requested = &stop;
  options.on_progress = [&](const std::string&, long done, long, const std::string&) {
    if (done == 14) stop = true;  // Mid-capture, as SIGINT would.
  };
  const CaptureSummary first = run_capture(session, lights, camera, options);
  EXPECT_EQ(first.status, CaptureSummary::Status::kInterrupted);
  EXPECT_EQ(lights.count_on(), 0);
  const int captured_first = first.frames_captured;
  EXPECT_GE(captured_first, 14);
  EXPECT_FALSE(session.complete());

  Session reopened = Session::open(tmp / "s");
  EXPECT_EQ(int(reopened.frames().size()), captured_first);
  FakeCamera camera2(lights);
  const CaptureSummary second = run_capture(reopened, lights, camera2, Instant());
  EXPECT_EQ(second.status, CaptureSummary::Status::kComplete);
  EXPECT_EQ(second.frames_already_present, captured_first);
  EXPECT_EQ(captured_first + second.frames_captured, int(plan_frames(stage).size()));
  EXPECT_EQ(camera2.frames, second.frames_captured);  // Nothing captured twice.
}

TEST(Sequencer, CameraTimeoutIsRetriedThenTheSessionStopsCleanlyAndResumably) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  const auto plan = plan_frames(stage);
  {
    Session session = Session::create(tmp / "s", stage, {});
    FakeLights lights(int(stage.leds.size()));
    FakeCamera camera(lights);
    camera.timeout_key = plan[12].request.sequence_key;
    camera.timeouts_left = 2;  // Two timeouts, then it works: within retries = 2.
    const CaptureSummary s = run_capture(session, lights, camera, Instant());
    EXPECT_EQ(s.status, CaptureSummary::Status::kComplete);
    EXPECT_EQ(s.camera_retries, 2);
  }
  testing::TempDir tmp2;
  Session session = Session::create(tmp2 / "s", stage, {});
  FakeLights lights(int(stage.leds.size()));
  FakeCamera camera(lights);
  camera.fail_after = 20;  // Unplugged after 20 frames.
  const CaptureSummary s = run_capture(session, lights, camera, Instant());
  EXPECT_EQ(s.status, CaptureSummary::Status::kCameraFailed);
  EXPECT_NE(s.message.find("resume"), std::string::npos);
  EXPECT_EQ(lights.count_on(), 0);
  EXPECT_EQ(s.frames_captured, 20);
  EXPECT_EQ(Session::open(tmp2 / "s").frames().size(), 20u);
  // Reconnected: resume finishes the rest.
  FakeCamera replugged(lights);
  Session again = Session::open(tmp2 / "s");
  EXPECT_EQ(run_capture(again, lights, replugged, Instant()).status,
            CaptureSummary::Status::kComplete);
  EXPECT_EQ(replugged.frames, int(plan.size()) - 20);
}

TEST(Sequencer, DeadLedIsFlaggedAndTheCaptureContinues) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  Session session = Session::create(tmp / "s", stage, {});
  FakeLights lights(int(stage.leds.size()));
  FakeCamera camera(lights);
  camera.dead_leds = {2};
  const CaptureSummary s = run_capture(session, lights, camera, Instant());
  EXPECT_EQ(s.status, CaptureSummary::Status::kComplete);
  ASSERT_EQ(session.dead_leds().size(), 1u);
  EXPECT_EQ(session.dead_leds().begin()->first, 2);
  EXPECT_EQ(Session::open(tmp / "s").dead_leds().count(2), 1u);
}

TEST(Sequencer, LedsTheSceneHidesAreNotDeadButALoneDarkLedAmongThemIsNot) {
  // Half the dome lights nothing the camera sees (as behind an opaque backdrop): data, not faults.
  testing::TempDir tmp;
  const Stage stage = SmallStage(40);
  Session session = Session::create(tmp / "s", stage, {});
  FakeLights lights(int(stage.leds.size()));
  FakeCamera camera(lights);
  int lone = -1;
  for (int i = 0; i < int(stage.leds.size()); ++i) {
    if (stage.leds[i].dir_in_stage.z() < 0) camera.dead_leds.insert(i);
    if (lone < 0 && stage.leds[i].dir_in_stage.z() > 0.5) lone = i;
  }
  camera.dead_leds.insert(lone);  // And one broken LED among lit ones.
  EXPECT_EQ(run_capture(session, lights, camera, Instant()).status,
            CaptureSummary::Status::kComplete);
  ASSERT_EQ(session.dead_leds().size(), 1u);
  EXPECT_EQ(session.dead_leds().begin()->first, lone);
  EXPECT_EQ(session.led_signals().size(), stage.leds.size());
}

TEST(Sequencer, HardwareErrorStillSwitchesAllLedsOff) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  Session session = Session::create(tmp / "s", stage, {});
  struct ThrowingCamera : FakeCamera {
    using FakeCamera::FakeCamera;
    CapturedFrame capture(const FrameRequest& r) override {
      if (lights_.lit() == 3) throw HardwareError("fake camera: sensor overheated");
      return FakeCamera::capture(r);
    }
  };
  FakeLights lights(int(stage.leds.size()));
  ThrowingCamera camera(lights);
  EXPECT_THROW(run_capture(session, lights, camera, Instant()), HardwareError);
  EXPECT_EQ(lights.count_on(), 0);
  EXPECT_EQ(Session::open(tmp / "s").frames().size(), size_t(3 * 2 + 3 * 3));
}

// The frames directory stops being writable mid-capture (as when a disk fills or is unmounted; the
// tests run as root, so permissions cannot stand in for it: frames/ is swapped for a plain file).
TEST(Sequencer, FramesThatCannotBeSavedStopTheCaptureCleanlyAndResumeRecapturesThem) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  Session session = Session::create(tmp / "s", stage, {});
  struct SabotagingCamera : FakeCamera {
    using FakeCamera::FakeCamera;
    CapturedFrame capture(const FrameRequest& r) override {
      if (frames == 20) {
        // Let the writer thread save some frames first, so that there is something to keep.
        for (int i = 0; i < 500 && JournalLines() < 10; ++i) {
          std::this_thread::sleep_for(std::chrono::milliseconds(10));
        }
        std::filesystem::rename(dir / "frames", dir / "frames.away");
        std::ofstream(dir / "frames") << "not a directory";
      }
      return FakeCamera::capture(r);
    }
    int JournalLines() const {
      std::ifstream in(dir / "frames.jsonl");
      int n = 0;
      for (std::string line; std::getline(in, line);) ++n;
      return n;
    }
    std::filesystem::path dir;
  };
  FakeLights lights(int(stage.leds.size()));
  SabotagingCamera camera(lights);
  camera.dir = tmp / "s";
  const CaptureSummary stopped = run_capture(session, lights, camera, Instant());
  EXPECT_EQ(stopped.status, CaptureSummary::Status::kWriteFailed);
  EXPECT_NE(stopped.message.find("cannot save frames"), std::string::npos) << stopped.message;
  EXPECT_EQ(lights.count_on(), 0);
  EXPECT_LE(stopped.frames_captured, 20);
  EXPECT_GE(stopped.frames_captured, 9);  // At least the 10 journal lines waited for, bar one.

  std::filesystem::remove(tmp / "s" / "frames");
  std::filesystem::rename(tmp / "s" / "frames.away", tmp / "s" / "frames");
  Session reopened = Session::open(tmp / "s");
  EXPECT_EQ(int(reopened.frames().size()), stopped.frames_captured);
  for (const auto& [key, record] : reopened.frames()) {
    EXPECT_NO_THROW(reopened.load_frame(key)) << record.file;
  }
  FakeCamera healthy(lights);
  const CaptureSummary resumed = run_capture(reopened, lights, healthy, Instant());
  EXPECT_EQ(resumed.status, CaptureSummary::Status::kComplete);
  EXPECT_TRUE(reopened.complete());
  EXPECT_EQ(healthy.frames, int(plan_frames(stage).size()) - stopped.frames_captured);
}

// A kill inside a dead LED's bracket (the bracket split between two runs), or after its step's
// last frame but before the verdict was journaled: the resume still flags it.
TEST(Sequencer, ADeadLedIsFlaggedWhateverMomentTheCaptureWasKilledAt) {
  const Stage stage = SmallStage(12);
  const std::string first_of_dead = FrameKey{0, 5, 0, 0}.name(stage);
  for (const bool split_bracket : {true, false}) {
    testing::TempDir tmp;
    FakeLights lights(int(stage.leds.size()));
    {
      Session session = Session::create(tmp / "s", stage, {});
      FakeCamera camera(lights);
      camera.dead_leds = {5};
      std::atomic<bool> stop{false};
      SequencerOptions options = Instant();
      options.stop_requested = &stop;
      options.on_progress = [&](const std::string&, long, long, const std::string& frame) {
        if (split_bracket && frame == first_of_dead) stop = true;
      };
      run_capture(session, lights, camera, options);
    }
    if (!split_bracket) {
      // As if killed after the last frame: the signals and verdict lines never reached the journal.
      std::ifstream in(tmp / "s" / "frames.jsonl");
      std::string kept;
      for (std::string line; std::getline(in, line);) {
        if (line.find("led_signal") == std::string::npos &&
            line.find("dead_led") == std::string::npos) {
          kept += line + "\n";
        }
      }
      in.close();
      std::ofstream(tmp / "s" / "frames.jsonl", std::ios::trunc) << kept;
    }
    Session resumed = Session::open(tmp / "s");
    EXPECT_TRUE(resumed.dead_leds().empty());
    FakeCamera camera(lights);
    camera.dead_leds = {5};
    EXPECT_EQ(run_capture(resumed, lights, camera, Instant()).status,
              CaptureSummary::Status::kComplete);
    EXPECT_EQ(resumed.dead_leds().count(5), 1u) << "split bracket: " << split_bracket;
    EXPECT_EQ(resumed.dead_leds().size(), 1u);
    EXPECT_EQ(Session::open(tmp / "s").dead_leds().count(5), 1u);
  }
}

// The session folder is deleted (or unmounted) mid-capture: the capture stops as a storage
// failure naming the folder, and never recreates it half empty.
TEST(Sequencer, AVanishedSessionFolderStopsTheCaptureAndIsNotRecreated) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  Session session = Session::create(tmp / "s", stage, {});
  struct DeletingCamera : FakeCamera {
    using FakeCamera::FakeCamera;
    CapturedFrame capture(const FrameRequest& r) override {
      if (frames == 20) std::filesystem::remove_all(dir);
      return FakeCamera::capture(r);
    }
    std::filesystem::path dir;
  };
  FakeLights lights(int(stage.leds.size()));
  DeletingCamera camera(lights);
  camera.dir = tmp / "s";
  const CaptureSummary s = run_capture(session, lights, camera, Instant());
  EXPECT_EQ(s.status, CaptureSummary::Status::kWriteFailed);
  EXPECT_NE(s.message.find((tmp / "s").string() + " is gone"), std::string::npos) << s.message;
  EXPECT_EQ(lights.count_on(), 0);
  EXPECT_FALSE(std::filesystem::exists(tmp / "s"));
}

// Frames damaged after they were saved (truncated, overwritten, replaced by another image) are
// found when the session is read back and captured again; the intact ones are kept.
TEST(Sequencer, DamagedFramesAreFoundOnResumeAndCapturedAgain) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  FakeLights lights(int(stage.leds.size()));
  {
    Session session = Session::create(tmp / "s", stage, {});
    FakeCamera camera(lights);
    ASSERT_EQ(run_capture(session, lights, camera, Instant()).status,
              CaptureSummary::Status::kComplete);
  }
  const std::filesystem::path frames = tmp / "s" / "frames";
  const auto file = [&](const FrameKey& k) { return frames / (k.name(stage) + ".png"); };
  std::filesystem::resize_file(file({0, 1, 0, 0}), 100);               // Truncated.
  std::ofstream(file({0, 2, 1, 0}), std::ios::trunc) << "garbage";     // Overwritten.
  std::filesystem::copy_file(file({0, 3, 2, 0}), file({0, -1, 0, 0}),  // Another frame's image.
                             std::filesystem::copy_options::overwrite_existing);
  const int planned = int(plan_frames(stage).size());
  Session reopened = Session::open(tmp / "s");
  EXPECT_TRUE(reopened.complete());  // Before the check: the journal trusts every frame.
  const FrameCheck check = reopened.verify_frames();
  EXPECT_EQ(check.verified, planned - 3);
  ASSERT_EQ(check.damaged.size(), 3u);
  EXPECT_NE(check.damaged[0].find(file({0, -1, 0, 0}).string()), std::string::npos);
  EXPECT_EQ(reopened.missing_frames().size(), 3u);
  FakeCamera camera(lights);
  EXPECT_EQ(run_capture(reopened, lights, camera, Instant()).status,
            CaptureSummary::Status::kComplete);
  EXPECT_EQ(camera.frames, 3);
  Session again = Session::open(tmp / "s");
  EXPECT_EQ(again.verify_frames().verified, planned);
  EXPECT_EQ(again.load_frame({0, 2, 1, 0}).pixels[0], 50 + 120);  // LED 2 at 10 ms.
}

}  // namespace
}  // namespace ls
