// Hostile JSON and damaged journals: clear InputErrors naming the file (and line), never a crash.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/json_reader.h"
#include "lightstage/session.h"
#include "lightstage/stage.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;

std::string input_error(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

TEST(HostileInput, DeepNestingIsRefusedBeforeAnythingWalksIt) {
  const std::string deep(200000, '[');
  const std::string what = input_error([&] { (void)JsonReader::parse(deep, "deep.json"); });
  EXPECT_NE(what.find("deep.json: "), std::string::npos) << what;
  EXPECT_NE(what.find("nested deeper"), std::string::npos) << what;
  // Brackets inside strings do not count.
  EXPECT_NO_THROW((void)JsonReader::parse("{\"note\": \"" + std::string(1000, '[') + "\"}", "s"));
}

TEST(HostileInput, NumberBeyondADoubleNamesTheFile) {
  const std::string what = input_error(
      [&] { (void)parse_stage(R"({"camera": {"distance_m": 1e400}})", "lab_dome.json"); });
  EXPECT_NE(what.find("lab_dome.json: "), std::string::npos) << what;
  EXPECT_NE(what.find("range of a double"), std::string::npos) << what;
}

TEST(HostileInput, ImageHeaderClaimingTooMuchIsRefusedBeforeAllocating) {
  testing::TempDir dir;
  // A Radiance header of a 100000 x 50000 map (60 GB of float pixels) over a few bytes of data.
  const fs::path file = dir / "huge.hdr";
  std::ofstream(file, std::ios::binary)
      << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 50000 +X 100000\n"
      << std::string(64, '\x80');
  const std::string what = input_error([&] { (void)read_image(file); });
  EXPECT_NE(what.find("huge.hdr: the image's 100000x50000x3 float pixels needs"), std::string::npos)
      << what;
}

TEST(HostileInput, FrameHeaderClaimingTooMuchIsRefusedBeforeAllocating) {
  testing::TempDir dir;
  // A PNG whose header claims 200000 x 200000 16-bit RGB (240 GB) and holds no pixels.
  std::string ihdr = std::string("IHDR") + std::string("\x00\x03\x0d\x40", 4) +
                     std::string("\x00\x03\x0d\x40", 4) + std::string("\x10\x02\x00\x00\x00", 5);
  const uint32_t crc = crc32_of(ihdr.data(), ihdr.size());
  std::string png = std::string("\x89PNG\r\n\x1a\n", 8) + std::string("\x00\x00\x00\x0d", 4) + ihdr;
  for (int shift = 24; shift >= 0; shift -= 8) png += char((crc >> shift) & 0xff);
  png += std::string("\x00\x00\x00\x00IDAT\x35\xaf\x06\x1e", 12);  // Empty: no pixels.
  png += std::string("\x00\x00\x00\x00IEND\xae\x42\x60\x82", 12);
  const fs::path file = dir / "t000_led001_e0.png";
  std::ofstream(file, std::ios::binary) << png;
  const std::string what = input_error([&] { (void)read_raw_frame(file, 12); });
  EXPECT_NE(what.find("t000_led001_e0.png: the frame's 200000x200000x3 pixels needs"),
            std::string::npos)
      << what;
}

class DamagedJournal : public ::testing::Test {
 protected:
  void SetUp() override {
    Stage stage = stage_with_directions(fibonacci_dome_directions(4, 0));
    stage.camera.width = 8;
    stage.camera.height = 4;
    const auto plan = plan_frames(stage);
    Session s = Session::create(dir_ / "s", stage, {});
    CapturedFrame frame;
    frame.raw = {8, 4, 3, 12, std::vector<uint16_t>(8 * 4 * 3, 100)};
    frame.exposure_s = 0.01;
    for (int i = 0; i < 3; ++i) s.record_frame(plan[i], frame);
    first_frame_file_ = dir_ / "s" / "frames" / (plan[0].key.name(stage) + ".png");
  }
  void append(const std::string& line) {
    std::ofstream(dir_ / "s" / "frames.jsonl", std::ios::app) << line << "\n";
  }
  testing::TempDir dir_;
  fs::path first_frame_file_;
};

TEST_F(DamagedJournal, ValidJsonOfTheWrongShapeNamesTheJournalLine) {
  append(R"({"t": 0, "led": 0, "e": 0, "r": 0, "file": 5})");
  const std::string what = input_error([&] { (void)Session::open(dir_ / "s"); });
  EXPECT_NE(what.find("frames.jsonl:4: expected a frame"), std::string::npos) << what;
}

// Indices beyond the plan (or an int), as the session fuzz target wrote them, are named by line and
// field: unchecked, they would reach past the stage's LEDs and steps (out of range, UB).
TEST_F(DamagedJournal, IndicesBeyondThePlanNameTheJournalLineAndField) {
  const std::pair<const char*, const char*> cases[] = {
      {R"({"dead_led": 99, "reason": "x"})",
       "frames.jsonl:4: dead_led: expected an integer in [0, 3]"},
      {R"({"overrun": 7, "capture_s": 40, "interval_s": 30})", "frames.jsonl:4: overrun: expected"},
      {R"({"t": 1e40, "led": 0, "e": 0, "r": 0})",
       "frames.jsonl:4: t: expected an integer in [0, 0]"},
      {R"({"t": [1, 2], "led": 0, "e": 0, "r": 0})", "frames.jsonl:4: t: expected"},
      {R"({"led_signal": 18446744073709551615, "t": 0, "fraction": 1})", "led_signal: expected"}};
  for (const auto& [line, message] : cases) {
    fs::remove_all(dir_ / "s");
    SetUp();  // A fresh session of 3 frames: the line appended is line 4.
    append(line);
    const std::string what = input_error([&] { (void)Session::open(dir_ / "s"); });
    EXPECT_NE(what.find(message), std::string::npos) << what;
  }
}

// A frame's size or checksum, or the manifest's seed, given as a float far beyond its integer type
// (as the session fuzz target wrote them) is refused by name, not converted (undefined behaviour).
TEST_F(DamagedJournal, SizesChecksumsAndSeedsBeyondTheirTypesAreRefusedByName) {
  const std::string frame =
      R"({"t": 0, "led": 0, "e": 0, "r": 0, "file": "x.png", "exposure_s": 0.01, "gain": 1, )"
      R"("scene_time_s": 0, "at": "now", )";
  const std::pair<std::string, const char*> cases[] = {
      {frame + R"("bytes": 10, "crc32": 2.1951e28})",
       "frames.jsonl:4: crc32: expected an integer in [0, 4294967295]"},
      {frame + R"("bytes": -5, "crc32": 7})", "frames.jsonl:4: bytes: expected an integer"}};
  for (const auto& [line, message] : cases) {
    fs::remove_all(dir_ / "s");
    SetUp();
    append(line);
    const std::string what = input_error([&] { (void)Session::open(dir_ / "s"); });
    EXPECT_NE(what.find(message), std::string::npos) << what;
  }
  fs::remove_all(dir_ / "s");
  SetUp();
  const fs::path manifest = dir_ / "s" / "manifest.json";
  std::stringstream text;
  text << std::ifstream(manifest).rdbuf();
  std::string json = text.str();
  const size_t at = json.find("\"seed\": ");
  ASSERT_NE(at, std::string::npos) << json;
  const size_t end = json.find_first_of(",\n}", at + 8);
  json.replace(at, end - at, "\"seed\": 2.1951e28");
  std::ofstream(manifest) << json;
  const std::string what = input_error([&] { (void)Session::open(dir_ / "s"); });
  EXPECT_NE(what.find("seed"), std::string::npos) << what;
  EXPECT_NE(what.find("non-negative integer"), std::string::npos) << what;
}

TEST_F(DamagedJournal, NumberBeyondADoubleNamesTheJournalLine) {
  append(R"({"t": 0, "led": 0, "e": 0, "r": 0, "exposure_s": 1e400})");
  const std::string what = input_error([&] { (void)Session::open(dir_ / "s"); });
  EXPECT_NE(what.find("frames.jsonl:4: "), std::string::npos) << what;
}

TEST_F(DamagedJournal, FrameFileThatIsASymlinkLoopIsMissingNotACrash) {
  fs::remove(first_frame_file_);
  fs::create_symlink(first_frame_file_.filename(), first_frame_file_);  // Points at itself.
  const Session s = Session::open(dir_ / "s");
  EXPECT_EQ(s.frames().size(), 2u);  // That frame will be captured again.
}

}  // namespace
}  // namespace ls
