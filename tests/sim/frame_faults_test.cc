// Frame faults injected into the simulated camera during a capture: each bad frame is
// caught by its check on arrival, shot again and journaled, and nothing bad reaches the session:
// its frames are bit for bit those of a capture without faults (the simulator seeds each frame's
// noise with its plan key). A fault that persists marks the LED dead; a stuck LED stops the
// capture at its dark frames, resumable.
#include <gtest/gtest.h>

#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

using sim::SimStage;

// The default dome and scene at 96 x 96: every LED, the default three-exposure bracket.
Stage SmallStage() {
  Stage stage = default_stage();
  stage.camera.width = stage.camera.height = 96;
  return stage;
}

SequencerOptions Instant() {
  SequencerOptions options;
  options.sleep = [](double) {};
  return options;
}

uint64_t SequenceKey(const Stage& stage, const FrameKey& key) {
  for (const PlannedFrame& f : plan_frames(stage)) {
    if (f.key == key) return f.request.sequence_key;
  }
  ADD_FAILURE() << "no such frame";
  return 0;
}

class FrameFaults : public ::testing::Test {
 protected:
  FrameFaults() : stage_(SmallStage()), sim_(stage_, sim::default_scene(), 7) {}

  CaptureSummary Capture(const std::string& name) {
    Session session = Session::create(tmp_ / name, stage_, {});
    return run_capture(session, sim_.lights(), sim_.camera(), Instant());
  }

  // Every frame of session `a` is bit for bit the same frame in session `b`.
  void ExpectSameFrames(const std::string& a, const std::string& b) {
    const Session sa = Session::open(tmp_ / a), sb = Session::open(tmp_ / b);
    ASSERT_EQ(sa.frames().size(), sb.frames().size());
    for (const auto& [key, record] : sa.frames()) {
      EXPECT_EQ(sa.load_frame(key).pixels, sb.load_frame(key).pixels) << key.name(stage_);
    }
  }

  testing::TempDir tmp_;
  Stage stage_;
  SimStage sim_;
};

TEST_F(FrameFaults, ACleanCaptureRaisesNoAlarm) {
  const CaptureSummary summary = Capture("clean");
  EXPECT_EQ(summary.status, CaptureSummary::Status::kComplete);
  EXPECT_EQ(summary.frames_reshot, 0);
  const Session session = Session::open(tmp_ / "clean");
  for (const FrameProblem& p : session.frame_problems()) {
    ADD_FAILURE() << p.key.name(stage_) << ": " << p.problem;
  }
  EXPECT_TRUE(session.dead_leds().empty());
}

TEST_F(FrameFaults, StaleTornAndWrongLedFramesAreShotAgainAndNoneIsSaved) {
  Capture("clean");
  // LEDs on the camera's side of the dome, which light the scene (LEDs behind it leave frames
  // that are noise, where a swapped frame is harmless and cannot be told).
  std::vector<int> front;
  for (int i = 0; i < int(stage_.leds.size()); ++i) {
    if (stage_.leds[size_t(i)].dir_in_stage.z() > 0.5) front.push_back(i);
  }
  ASSERT_GE(front.size(), 30u);
  const FrameKey stale{0, front[3], 0, 0}, torn{0, front[15], 1, 0}, wrong{0, front[25], 2, 0};
  sim_.inject_frame_fault(SequenceKey(stage_, stale), SimStage::FrameFault::kStale);
  sim_.inject_frame_fault(SequenceKey(stage_, torn), SimStage::FrameFault::kTorn);
  sim_.inject_frame_fault(SequenceKey(stage_, wrong), SimStage::FrameFault::kWrongLed);
  const CaptureSummary summary = Capture("faulty");
  EXPECT_EQ(summary.status, CaptureSummary::Status::kComplete);
  EXPECT_EQ(summary.frames_reshot, 3);
  const Session session = Session::open(tmp_ / "faulty");
  std::vector<FrameKey> rejected;
  for (const FrameProblem& p : session.frame_problems()) {
    rejected.push_back(p.key);
    EXPECT_EQ(p.attempt, 0);
    EXPECT_NE(p.problem.find("disagrees"), std::string::npos) << p.problem;
  }
  EXPECT_EQ(rejected, (std::vector<FrameKey>{stale, torn, wrong}));
  EXPECT_TRUE(session.dead_leds().empty());
  ExpectSameFrames("clean", "faulty");
  // A torn frame is located: its lower half.
  const std::string torn_problem = session.frame_problems()[1].problem;
  EXPECT_NE(torn_problem.find("rows 48-95"), std::string::npos) << torn_problem;
}

TEST_F(FrameFaults, AFaultThatPersistsMarksTheLedDeadAndTheCaptureGoesOn) {
  const FrameKey stuck{0, 10, 1, 0};
  sim_.inject_frame_fault(SequenceKey(stage_, stuck), SimStage::FrameFault::kStale, 100);
  const CaptureSummary summary = Capture("persistent");
  EXPECT_EQ(summary.status, CaptureSummary::Status::kComplete);
  EXPECT_EQ(summary.frames_reshot, SequencerOptions{}.frame_reshoots);
  const Session session = Session::open(tmp_ / "persistent");
  EXPECT_TRUE(session.complete());
  EXPECT_EQ(int(session.frame_problems().size()), SequencerOptions{}.frame_reshoots + 1);
  ASSERT_EQ(session.dead_leds().count(10), 1u);
  EXPECT_NE(session.dead_leds().at(10).find("t000_led"), std::string::npos);
}

TEST_F(FrameFaults, AStuckLedStopsTheCaptureAtTheDarkFramesAndAResumeCompletesIt) {
  sim_.set_stuck_led(5);
  const CaptureSummary stopped = Capture("stuck");
  EXPECT_EQ(stopped.status, CaptureSummary::Status::kDarkFramesLit);
  EXPECT_NE(stopped.message.find("t000_dark_e0_r0"), std::string::npos) << stopped.message;
  EXPECT_NE(stopped.message.find("resume"), std::string::npos) << stopped.message;
  sim_.set_stuck_led(-1);
  Session session = Session::open(tmp_ / "stuck");
  EXPECT_EQ(int(session.frame_problems().size()), SequencerOptions{}.frame_reshoots + 1);
  const CaptureSummary resumed = run_capture(session, sim_.lights(), sim_.camera(), Instant());
  EXPECT_EQ(resumed.status, CaptureSummary::Status::kComplete);
  Capture("clean");
  ExpectSameFrames("clean", "stuck");
}

// camera.sync.trigger "line": the simulator's controller pulses its trigger line and its camera
// exposes on the edge it sees. The frames are those of a software trigger; a wire that breaks in
// the middle stops the capture with the frames taken saved, and a resume after the repair ends it.
TEST_F(FrameFaults, ALineTriggeredCaptureMatchesTheSoftwareOneAndABrokenWireStopsItResumably) {
  stage_.leds.resize(12);
  SimStage software(stage_, sim::default_scene(), 7);
  Session plain = Session::create(tmp_ / "software", stage_, {});
  ASSERT_EQ(run_capture(plain, software.lights(), software.camera(), Instant()).status,
            CaptureSummary::Status::kComplete);

  Stage wired = stage_;
  wired.camera.sync.trigger = "line";
  wired.camera.sync.gpio_chip = "gpiochip1";  // The controller's trigger output, no LED's line.
  wired.camera.sync.gpio_line = 23;
  SimStage sim(wired, sim::default_scene(), 7);
  EXPECT_THROW(software.camera().set_trigger_line([] {}), HardwareError);  // Not line-triggered.
  EXPECT_THROW(software.lights().pulse_trigger(), HardwareError);
  wire_trigger(wired.camera, sim.lights(), sim.camera());
  SequencerOptions options = Instant();
  options.on_progress = [&](const std::string&, long done, long, const std::string&) {
    if (done == 20) sim.set_trigger_wire_broken(true);
  };
  Session session = Session::create(tmp_ / "line", wired, {});
  const CaptureSummary broken = run_capture(session, sim.lights(), sim.camera(), options);
  EXPECT_EQ(broken.status, CaptureSummary::Status::kCameraFailed);
  EXPECT_NE(broken.message.find("trigger line was pulsed and the camera saw no edge"),
            std::string::npos)
      << broken.message;
  EXPECT_GE(Session::open(tmp_ / "line").frames().size(), 20u);  // Nothing taken is lost.

  sim.set_trigger_wire_broken(false);
  Session again = Session::open(tmp_ / "line");
  EXPECT_EQ(run_capture(again, sim.lights(), sim.camera(), Instant()).status,
            CaptureSummary::Status::kComplete);
  ExpectSameFrames("software", "line");
}

}  // namespace
}  // namespace ls
