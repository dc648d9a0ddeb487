// Capture over time: plans with a list of times, scene times of frames, waiting for a
// step's start, overruns and resume across time steps.
#include <gtest/gtest.h>

#include <atomic>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "tests/lightstage/controller/fake_hardware.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

using testing::FakeCamera;
using testing::FakeLights;

Stage SmallTimedStage(std::vector<double> times_s) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(6, 0));
  stage.camera.width = 8;
  stage.camera.height = 4;
  stage.plan.times_s = std::move(times_s);
  stage.plan.time_steps = int(stage.plan.times_s.size());
  return stage;
}

// A fake camera on a fake clock: every frame takes `frame_s` seconds of it, and it notes the
// clock and the scene time of each frame it takes.
struct ClockedCamera : FakeCamera {
  ClockedCamera(const FakeLights& lights, double* now_s, double frame_s)
      : FakeCamera(lights), now_s(now_s), frame_s(frame_s) {}
  CapturedFrame capture(const FrameRequest& r) override {
    taken.push_back({*now_s, r.scene_time_s});
    *now_s += frame_s;
    return FakeCamera::capture(r);
  }
  double* now_s;
  double frame_s;
  std::vector<std::pair<double, double>> taken;  // (clock, scene time) per frame.
};

// A stage file with a small generated dome and the given plan, e.g. {"plan": {...}}.
std::string with_layout(const std::string& json) {
  return R"({"layout": {"type": "fibonacci", "count": 6}, )" + json.substr(1);
}

std::string expect_stage_error(const std::string& json) {
  try {
    parse_stage(with_layout(json), "timed.json");
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for " << json;
  return "";
}

TEST(TimeSteps, TimesListSetsTheStepsAndRoundTrips) {
  const Stage stage =
      parse_stage(with_layout(R"({"plan": {"times_s": [0, 2.5, 10]}})"), "timed.json");
  EXPECT_EQ(stage.plan.time_steps, 3);
  EXPECT_DOUBLE_EQ(stage.plan.step_time_s(1), 2.5);
  EXPECT_DOUBLE_EQ(stage.plan.step_interval_s(1), 7.5);
  EXPECT_DOUBLE_EQ(stage.plan.step_interval_s(2), 0.0);  // The last step has no next one.
  const Stage again = parse_stage(stage_to_json(stage), "again.json");
  EXPECT_EQ(again.plan.times_s, stage.plan.times_s);
  // Count and interval still work, and give the same step times.
  const Stage counted =
      parse_stage(with_layout(R"({"plan": {"time_steps": 3, "interval_s": 4}})"), "c.json");
  EXPECT_DOUBLE_EQ(counted.plan.step_time_s(2), 8.0);
  EXPECT_DOUBLE_EQ(counted.plan.step_interval_s(0), 4.0);
}

TEST(TimeSteps, TimesListErrorsNameTheFileAndTheField) {
  const std::string not_increasing = expect_stage_error(R"({"plan": {"times_s": [0, 5, 5]}})");
  EXPECT_NE(not_increasing.find("timed.json"), std::string::npos) << not_increasing;
  EXPECT_NE(not_increasing.find("plan.times_s[2]"), std::string::npos) << not_increasing;
  EXPECT_NE(not_increasing.find("increase"), std::string::npos) << not_increasing;
  const std::string negative = expect_stage_error(R"({"plan": {"times_s": [-1, 5]}})");
  EXPECT_NE(negative.find("plan.times_s[0]"), std::string::npos) << negative;
  const std::string both = expect_stage_error(R"({"plan": {"time_steps": 2, "times_s": [0, 5]}})");
  EXPECT_NE(both.find("plan.times_s"), std::string::npos) << both;
  EXPECT_NE(both.find("not both"), std::string::npos) << both;
  const std::string empty = expect_stage_error(R"({"plan": {"times_s": []}})");
  EXPECT_NE(empty.find("plan.times_s"), std::string::npos) << empty;
  const std::string not_number = expect_stage_error(R"({"plan": {"times_s": [0, "later"]}})");
  EXPECT_NE(not_number.find("plan.times_s[1]"), std::string::npos) << not_number;
}

TEST(TimeSteps, FramesCarryTheirStepsSceneTimeInTheRequestAndTheJournal) {
  testing::TempDir tmp;
  const Stage stage = SmallTimedStage({0, 7, 30});
  Session session = Session::create(tmp / "s", stage, {});
  FakeLights lights(int(stage.leds.size()));
  double now = 0;
  ClockedCamera camera(lights, &now, 0.01);
  SequencerOptions options;
  options.sleep = [](double) {};
  options.clock_s = [&] { return now; };
  ASSERT_EQ(run_capture(session, lights, camera, options).status,
            CaptureSummary::Status::kComplete);
  const Session reopened = Session::open(tmp / "s");
  ASSERT_EQ(reopened.frames().size(), plan_frames(stage).size());
  for (const auto& [key, record] : reopened.frames()) {
    EXPECT_DOUBLE_EQ(record.scene_time_s, stage.plan.times_s[key.time_step]) << key.name(stage);
  }
  std::set<double> scene_times;
  for (const auto& [clock, scene_time] : camera.taken) scene_times.insert(scene_time);
  EXPECT_EQ(scene_times, (std::set<double>{0, 7, 30}));
  // Not in real time: the steps follow each other at once (no sleeping, the clock only counts
  // frames), however far apart their scene times are.
  EXPECT_NEAR(now, 0.01 * double(plan_frames(stage).size()), 1e-9);
}

TEST(TimeSteps, RealTimeWaitsForEachStepsStartTime) {
  testing::TempDir tmp;
  const Stage stage = SmallTimedStage({0, 10, 12});
  Session session = Session::create(tmp / "s", stage, {});
  FakeLights lights(int(stage.leds.size()));
  double now = 100;  // The schedule is relative to the start of the run.
  const int frames_per_step = int(plan_frames(stage).size()) / 3;
  ClockedCamera camera(lights, &now, 0.25);
  SequencerOptions options;
  options.sleep = [&](double s) { now += s; };
  options.clock_s = [&] { return now; };
  options.wait_for_time_steps = true;
  const CaptureSummary summary = run_capture(session, lights, camera, options);
  ASSERT_EQ(summary.status, CaptureSummary::Status::kComplete);
  ASSERT_EQ(int(camera.taken.size()), 3 * frames_per_step);
  EXPECT_NEAR(camera.taken[0].first, 100.0, 1e-9);
  // Step 1 waits for 100 + 10 s; step 0 took 24 x 0.25 = 6 s.
  EXPECT_NEAR(camera.taken[frames_per_step].first, 110.0, 0.1 + 1e-9);
  EXPECT_GE(camera.taken[frames_per_step].first, 110.0 - 1e-6);
  // Step 1 takes 6 s, past step 2's start at 112: step 2 starts at once, and step 1 overran.
  EXPECT_NEAR(camera.taken[2 * frames_per_step].first,
              camera.taken[frames_per_step].first + frames_per_step * 0.25, 1e-9);
  ASSERT_EQ(summary.overruns.size(), 1u);
  EXPECT_EQ(summary.overruns[0].time_step, 1);
  EXPECT_NEAR(summary.overruns[0].capture_s, frames_per_step * 0.25, 1e-9);
  EXPECT_DOUBLE_EQ(summary.overruns[0].interval_s, 2.0);
}

TEST(TimeSteps, AnOverrunIsReportedInTheSummaryTheManifestAndAfterReopening) {
  testing::TempDir tmp;
  const Stage stage = SmallTimedStage({0, 10, 12, 100});
  Session session = Session::create(tmp / "s", stage, {});
  FakeLights lights(int(stage.leds.size()));
  double now = 0;
  ClockedCamera camera(lights, &now, 0.25);  // 24 frames a step: 6 s.
  SequencerOptions options;
  options.sleep = [](double) {};
  options.clock_s = [&] { return now; };
  const CaptureSummary summary = run_capture(session, lights, camera, options);
  ASSERT_EQ(summary.status, CaptureSummary::Status::kComplete);
  // Step 0 (6 s of 10) and step 2 (6 s of 88) fit; step 1 (6 s of 2) does not; step 3 is last.
  ASSERT_EQ(summary.overruns.size(), 1u);
  EXPECT_EQ(summary.overruns[0].time_step, 1);
  std::ifstream in(tmp / "s" / "manifest.json");
  const nlohmann::json manifest = nlohmann::json::parse(in);
  ASSERT_EQ(manifest["time_step_overruns"].size(), 1u);
  EXPECT_EQ(manifest["time_step_overruns"][0]["time_step"].get<int>(), 1);
  EXPECT_DOUBLE_EQ(manifest["time_step_overruns"][0]["scene_time_s"].get<double>(), 10.0);
  EXPECT_DOUBLE_EQ(manifest["time_step_overruns"][0]["interval_s"].get<double>(), 2.0);
  const Session reopened = Session::open(tmp / "s");
  ASSERT_EQ(reopened.time_step_overruns().size(), 1u);
  EXPECT_NEAR(reopened.time_step_overruns().at(1).capture_s, 6.0, 1e-9);
}

TEST(TimeSteps, ResumeOfAnInterruptedMultiStepCaptureTakesExactlyTheMissingFrames) {
  testing::TempDir tmp;
  const Stage stage = SmallTimedStage({0, 5, 20});
  const auto plan = plan_frames(stage);
  const int frames_per_step = int(plan.size()) / 3;
  Session session = Session::create(tmp / "s", stage, {});
  FakeLights lights(int(stage.leds.size()));
  double now = 0;
  ClockedCamera camera(lights, &now, 0.0);
  std::atomic<bool> stop{false};
  SequencerOptions options;
  options.sleep = [](double) {};
  options.clock_s = [&] { return now; };
  options.stop_requested = &stop;
  const int stop_at = frames_per_step + 5;  // In the middle of step 1.
  options.on_progress = [&](const std::string&, long done, long, const std::string&) {
    if (done == stop_at) stop = true;
  };
  const CaptureSummary first = run_capture(session, lights, camera, options);
  ASSERT_EQ(first.status, CaptureSummary::Status::kInterrupted);
  EXPECT_EQ(lights.count_on(), 0);
  std::set<FrameKey> before;
  const Session interrupted = Session::open(tmp / "s");
  for (const auto& [key, record] : interrupted.frames()) before.insert(key);
  EXPECT_GE(int(before.size()), stop_at);
  EXPECT_LT(int(before.size()), 2 * frames_per_step);

  Session reopened = Session::open(tmp / "s");
  ClockedCamera camera2(lights, &now, 0.0);
  SequencerOptions resume;
  resume.sleep = [](double) {};
  resume.clock_s = [&] { return now; };
  const CaptureSummary second = run_capture(reopened, lights, camera2, resume);
  ASSERT_EQ(second.status, CaptureSummary::Status::kComplete);
  EXPECT_EQ(second.frames_already_present, int(before.size()));
  EXPECT_EQ(camera2.frames, int(plan.size() - before.size()));  // Nothing captured twice.
  // The second run took exactly the planned frames that were missing, at their steps' times.
  std::set<FrameKey> after;
  const Session completed = Session::open(tmp / "s");
  for (const auto& [key, record] : completed.frames()) {
    after.insert(key);
    EXPECT_DOUBLE_EQ(record.scene_time_s, stage.plan.times_s[key.time_step]);
  }
  EXPECT_EQ(after.size(), plan.size());
  for (const auto& [clock, scene_time] : camera2.taken) EXPECT_GE(scene_time, 5.0);
  for (const FrameKey& key : before) EXPECT_LE(key.time_step, 1);
}

}  // namespace
}  // namespace ls
