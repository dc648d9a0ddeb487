#include "lightstage/session.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "lightstage/errors.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

Stage SmallStage() {
  Stage stage = stage_with_directions(fibonacci_dome_directions(5, 0));
  stage.camera.width = 8;
  stage.camera.height = 4;
  stage.plan.dark_frames = 2;
  return stage;
}

CapturedFrame Frame(uint16_t value) {
  CapturedFrame f;
  f.raw = {8, 4, 3, 12, std::vector<uint16_t>(8 * 4 * 3, value)};
  f.exposure_s = 0.01;
  return f;
}

TEST(Session, PlanHasDarksThenEachLedsBracketPerTimeStepWithUniqueKeys) {
  Stage stage = SmallStage();
  stage.plan.time_steps = 2;
  stage.plan.interval_s = 60;
  const auto plan = plan_frames(stage);
  // Per step: 3 exposures x (2 darks + 5 LEDs).
  ASSERT_EQ(plan.size(), 2u * 3 * (2 + 5));
  EXPECT_TRUE(plan[0].key.is_dark());
  EXPECT_EQ(plan[6].key.led_index, 0);
  std::set<uint64_t> keys;
  for (const auto& f : plan) keys.insert(f.request.sequence_key);
  EXPECT_EQ(keys.size(), plan.size());
  EXPECT_EQ(plan.back().request.scene_time_s, 60.0);
}

TEST(Session, RecordedFramesSurviveReopeningAndMissingIsThePlanMinusTheJournal) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  auto plan = plan_frames(stage);
  {
    Session s = Session::create(tmp / "s", stage, {});
    for (int i = 0; i < 10; ++i) s.record_frame(plan[i], Frame(uint16_t(100 + i)));
    s.mark_dead_led(3, "test");
  }
  const Session s = Session::open(tmp / "s");
  EXPECT_EQ(s.frames().size(), 10u);
  EXPECT_EQ(s.missing_frames().size(), plan.size() - 10);
  EXPECT_EQ(s.missing_frames().front().key, plan[10].key);
  EXPECT_EQ(s.load_frame(plan[7].key).pixels[0], 107);
  EXPECT_EQ(s.dead_leds().count(3), 1u);
  EXPECT_EQ(s.stage().leds.size(), stage.leds.size());
}

TEST(Session, TornJournalLineAndMissingFrameFileAreRecapturedNotTrusted) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  auto plan = plan_frames(stage);
  {
    Session s = Session::create(tmp / "s", stage, {});
    for (int i = 0; i < 4; ++i) s.record_frame(plan[i], Frame(7));
  }
  // A kill during an append leaves a partial line; a lost file leaves a dangling entry.
  std::ofstream(tmp / "s" / "frames.jsonl", std::ios::app) << "{\"t\": 0, \"led\": 1, \"e";
  std::filesystem::remove(tmp / "s" / "frames" / (plan[2].key.name(stage) + ".png"));
  {
    Session s = Session::open(tmp / "s");
    EXPECT_EQ(s.frames().size(), 3u);
    EXPECT_EQ(s.missing_frames().front().key, plan[2].key);
    s.record_frame(plan[2], Frame(7));  // Appended after the cut, not onto the torn line.
  }
  EXPECT_EQ(Session::open(tmp / "s").frames().size(), 4u);
}

// Garbage in the middle of the journal is damage, not "an interrupted write" (only the
// last line can be that); it is ignored, and the frames around it are kept.
TEST(Session, GarbageMidJournalIsCalledDamageAndIgnored) {
  testing::TempDir tmp;
  const Stage stage = SmallStage();
  auto plan = plan_frames(stage);
  {
    Session s = Session::create(tmp / "s", stage, {});
    s.record_frame(plan[0], Frame(7));
  }
  std::ofstream(tmp / "s" / "frames.jsonl", std::ios::app) << "\x01garbage}\n";
  Session::open(tmp / "s").record_frame(plan[1], Frame(7));  // After the garbage line.
  ::testing::internal::CaptureStderr();
  const Session s = Session::open(tmp / "s");
  const std::string said = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(s.frames().size(), 2u);
  EXPECT_NE(said.find("frames.jsonl:2: not a journal record (the journal is damaged"),
            std::string::npos)
      << said;
  EXPECT_EQ(said.find("interrupted"), std::string::npos) << said;
}

TEST(Session, RefusesToOverwriteAnExistingSessionAndNamesNonSessions) {
  testing::TempDir tmp;
  Session::create(tmp / "s", SmallStage(), {});
  EXPECT_THROW(Session::create(tmp / "s", SmallStage(), {}), InputError);
  try {
    Session::open(tmp.path());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("manifest.json"), std::string::npos);
  }
}

// A manifest.json that is a folder is called one, not "invalid JSON".
TEST(Session, AManifestThatIsAFolderIsCalledOne) {
  testing::TempDir tmp;
  std::filesystem::create_directories(tmp / "s" / "manifest.json");
  try {
    Session::open(tmp / "s");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("manifest.json: expected a file, found a folder"),
              std::string::npos)
        << e.what();
  }
}

TEST(Session, UnwritableDirectoryIsRefusedBeforeCapture) {
  if (geteuid() == 0) {
    // Root ignores permissions; use a path under a regular file instead.
    testing::TempDir tmp;
    std::ofstream(tmp / "file") << "x";
    EXPECT_THROW(Session::create(tmp / "file" / "s", SmallStage(), {}), InputError);
    return;
  }
  EXPECT_THROW(Session::create("/proc/lightstage-session", SmallStage(), {}), InputError);
}

}  // namespace
}  // namespace ls
