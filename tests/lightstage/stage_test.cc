#include "lightstage/stage.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "lightstage/errors.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

// Expects parse_stage to throw an InputError whose message contains every fragment.
void ExpectStageError(const std::string& json, std::initializer_list<std::string> fragments) {
  try {
    parse_stage(json, "bad_stage.json");
    ADD_FAILURE() << "no error for: " << json;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("bad_stage.json"), std::string::npos) << msg;
    for (const auto& f : fragments)
      EXPECT_NE(msg.find(f), std::string::npos) << "'" << f << "' not in: " << msg;
  }
}

TEST(Stage, DefaultDomeIsAboutOneHundredFiftyUnitLedsOverTheUpperHemisphereAndARing) {
  const Stage stage = default_stage();
  EXPECT_GE(stage.leds.size(), 140u);
  EXPECT_LE(stage.leds.size(), 165u);
  double lowest = 1;
  int below = 0;
  for (const auto& led : stage.leds) {
    EXPECT_NEAR(led.dir_in_stage.norm(), 1.0, 1e-12);
    lowest = std::min(lowest, led.dir_in_stage.y());
    below += led.dir_in_stage.y() < -1e-6;
  }
  EXPECT_LT(lowest, -0.1);   // A ring below the horizon...
  EXPECT_GT(lowest, -0.25);  // ...but only one.
  EXPECT_GT(below, 5);
  // The zenith is an LED (the geodesic is rotated to put a vertex there).
  EXPECT_NEAR(stage.leds.front().dir_in_stage.y(), 1.0, 1e-12);
  std::cout << "default dome: " << stage.leds.size() << " LEDs, " << below
            << " below the horizon\n";
}

TEST(Stage, GeodesicNeighboursAreEvenlySpaced) {
  const auto dirs = geodesic_dome_directions(5, -11.5);
  double min_nn = 10, max_nn = 0;
  for (size_t i = 0; i < dirs.size(); ++i) {
    double best = 10;
    for (size_t j = 0; j < dirs.size(); ++j) {
      if (i != j) best = std::min(best, std::acos(std::clamp(dirs[i].dot(dirs[j]), -1.0, 1.0)));
    }
    min_nn = std::min(min_nn, best);
    max_nn = std::max(max_nn, best);
  }
  EXPECT_LT(max_nn / min_nn, 1.35);  // Geodesic spacing varies by ~20% at most.
}

TEST(Stage, FibonacciDomeHasTheRequestedCountAboveTheCut) {
  for (int n : {20, 40, 80, 150, 300}) {
    const auto dirs = fibonacci_dome_directions(n, -11.5);
    ASSERT_EQ(int(dirs.size()), n);
    for (const auto& d : dirs) {
      EXPECT_NEAR(d.norm(), 1.0, 1e-12);
      EXPECT_GE(d.y(), std::sin(-11.5 * M_PI / 180) - 1e-12);
    }
  }
}

TEST(Stage, JsonRoundTripPreservesEverything) {
  Stage stage = default_stage();
  stage.leds[3].color_gain = {0.9, 1.0, 1.1};
  stage.leds[3].intensity = 1.25;
  stage.leds[4].distance_m = 1.5;
  stage.leds[5].gpio_chip = "gpiochip0";
  stage.leds[5].gpio_line = 17;
  stage.leds[5].active_low = true;
  stage.camera.response.kind = CameraResponse::Kind::kGamma;
  stage.camera.response.gamma = 2.2;
  stage.plan.time_steps = 3;
  stage.plan.led_order = {2, 1, 0};
  stage.camera.sync = {"line", "Line2", "gpiochip1", 23, 250, "Line1"};
  const Stage back = parse_stage(stage_to_json(stage), "roundtrip.json");
  EXPECT_EQ(back.camera.sync.trigger, "line");
  EXPECT_EQ(back.camera.sync.input, "Line2");
  EXPECT_EQ(back.camera.sync.gpio_chip, "gpiochip1");
  EXPECT_EQ(back.camera.sync.gpio_line, 23);
  EXPECT_EQ(back.camera.sync.pulse_us, 250);
  EXPECT_EQ(back.camera.sync.exposure_active_output, "Line1");
  EXPECT_EQ(parse_stage(stage_to_json(default_stage()), "d.json").camera.sync.gpio_line, -1);
  ASSERT_EQ(back.leds.size(), stage.leds.size());
  for (size_t i = 0; i < stage.leds.size(); ++i) {
    EXPECT_EQ(back.leds[i].id, stage.leds[i].id);
    EXPECT_NEAR((back.leds[i].dir_in_stage - stage.leds[i].dir_in_stage).norm(), 0, 1e-12);
    EXPECT_EQ(back.leds[i].color_gain, stage.leds[i].color_gain);
    EXPECT_EQ(back.leds[i].intensity, stage.leds[i].intensity);
    EXPECT_EQ(back.leds[i].gpio_line, stage.leds[i].gpio_line);
  }
  EXPECT_NEAR(*back.leds[4].distance_m, 1.5, 1e-12);
  EXPECT_TRUE(back.leds[5].active_low);
  EXPECT_EQ(back.camera.response.kind, CameraResponse::Kind::kGamma);
  EXPECT_EQ(back.camera.bracket.size(), stage.camera.bracket.size());
  EXPECT_EQ(back.plan.time_steps, 3);
  EXPECT_EQ(back.plan.led_order, stage.plan.led_order);
  EXPECT_EQ(back.capture_order(), (std::vector<int>{2, 1, 0}));
}

// A session's stage is read back on every resume and written again: its text must not move, so
// that a resumed capture writes the bytes of an uninterrupted one (directions are not
// renormalised an ulp away each time).
TEST(Stage, ReadingAndWritingAgainGivesTheSameText) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(40, -10));
  const std::string once = stage_to_json(stage);
  const std::string twice = stage_to_json(parse_stage(once, "once.json"));
  EXPECT_EQ(stage_to_json(parse_stage(twice, "twice.json")), twice);
  EXPECT_EQ(twice, once);
}

TEST(Stage, GeneratedLayoutAndPositions) {
  const Stage s = parse_stage(R"({"layout": {"type": "fibonacci", "count": 40}})", "s.json");
  EXPECT_EQ(s.leds.size(), 40u);
  const Stage p =
      parse_stage(R"({"leds": [{"position": [0, 2, 0]}, {"direction": [1, 0, 0]}]})", "p.json");
  EXPECT_NEAR(*p.leds[0].distance_m, 2.0, 1e-12);
  EXPECT_NEAR(p.leds[0].dir_in_stage.y(), 1.0, 1e-12);
  EXPECT_FALSE(p.leds[1].distance_m.has_value());
  // A component near the largest double (a fuzz finding: its square overflowed and the "unit"
  // direction came out 0): still a unit vector along it.
  const Stage huge = parse_stage(
      R"({"leds": [{"direction": [0.88, 0.32, -0.33e308]}, {"direction": [0, 1, 0]}]})", "h.json");
  EXPECT_NEAR(huge.leds[0].dir_in_stage.norm(), 1.0, 1e-12);
  EXPECT_NEAR(huge.leds[0].dir_in_stage.z(), -1.0, 1e-12);
}

TEST(Stage, ErrorsNameTheFileTheFieldAndWhatWasExpected) {
  ExpectStageError("{ \"leds\": [ }", {"not valid JSON", ":1:"});
  ExpectStageError(R"({"leds": []})", {"leds", "at least one LED"});
  ExpectStageError(R"({"leds": [{"direction": [0, 0]}]})", {"leds[0].direction", "3 numbers"});
  ExpectStageError(R"({"leds": [{"direction": [0, 0, 0]}]})", {"leds[0].direction", "non-zero"});
  ExpectStageError(R"({"leds": [{"position": [1e308, 1e308, 0]}]})",
                   {"leds[0].position", "within 1000 km"});
  ExpectStageError(R"({"leds": [{"direction": [0, 1, 0], "position": [0, 1, 0]}]})",
                   {"leds[0]", "exactly one of"});
  ExpectStageError(R"({"leds": [{"direction": [0, 1, 0], "intensty": 2}]})",
                   {"leds[0].intensty", "unknown field"});
  ExpectStageError(R"({"leds": [{"direction": [0, 1, 0], "intensity": -2}]})",
                   {"leds[0].intensity", "positive"});
  // A key given twice: the second would silently replace the first.
  ExpectStageError(R"({"layout": {"type": "fibonacci", "count": 10},
                       "camera": {"width": 32, "width": 64}})",
                   {"camera.width: given twice"});
  ExpectStageError(R"({"leds": [{"direction": [0, 1, 0]}, {"direction": [1, 0, 0], "id": 3,
                       "direction": [0, 0, 1]}]})",
                   {"leds[1].direction: given twice"});
  // Values that overflow (or vanish in) the floats the pipeline computes in (a direction is
  // normalised in double first: GeneratedLayoutAndPositions).
  ExpectStageError(R"({"leds": [{"direction": [0, 1, 0], "intensity": 1e39}]})",
                   {"leds[0].intensity", "32-bit float", "1e+39"});
  ExpectStageError(R"({"leds": [{"direction": [0, 1, 0], "intensity": 1e-39}]})",
                   {"leds[0].intensity", "32-bit float"});
  ExpectStageError(R"({"leds": [{"direction": [0, 1, 0], "color": [1e39, 1, 1]}]})",
                   {"leds[0].color", "32-bit float"});
  ExpectStageError(R"({"layout": {"type": "fibonacci", "count": 10},
                       "camera": {"radiometric_scale": 1e39}})",
                   {"camera.radiometric_scale", "32-bit float"});
  ExpectStageError(
      R"({"leds": [{"id": 1, "direction": [0, 1, 0]}, {"id": 1, "direction": [1, 0, 0]}]})",
      {"leds[1].id", "unique"});
  ExpectStageError(R"({"layout": {"type": "fibonacci", "count": 10},
                       "camera": {"bracket": [{"exposure_s": -0.1}]}})",
                   {"camera.bracket[0].exposure_s", "positive", "-0.1"});
  ExpectStageError(R"({"layout": {"type": "fibonacci", "count": 10}, "camera": {"bit_depth": 20}})",
                   {"camera.bit_depth", "[8, 16]", "20"});
  ExpectStageError(
      R"({"layout": {"type": "fibonacci", "count": 10}, "camera": {"backend": "usb"}})",
      {"camera.backend", "\"sim\""});
  ExpectStageError(R"({"layout": {"type": "fibonacci", "count": 10}, "plan": {"led_order": [99]}})",
                   {"plan.led_order[0]", "id of an LED"});
  ExpectStageError(R"({"layout": {"type": "geodesic"}})", {"layout.frequency", "missing"});
  ExpectStageError(
      R"({"layout": {"type": "fibonacci", "count": 10}, "camera": {"sync": {"trigger": "hw"}}})",
      {"camera.sync.trigger", "\"line\""});
  ExpectStageError(R"({"layout": {"type": "fibonacci", "count": 10},
                       "camera": {"sync": {"gpio": {"chip": "gpiochip0", "line": -3}}}})",
                   {"camera.sync.gpio.line", "-3"});
  ExpectStageError(R"({"layout": {"type": "fibonacci", "count": 10},
                       "camera": {"sync": {"pulse_us": 0}}})",
                   {"camera.sync.pulse_us", "microseconds"});
  ExpectStageError(R"({"layout": {"type": "fibonacci", "count": 10},
                       "camera": {"sync": {"trigger": "line", "exposure_active_output": "Line0"}}})",
                   {"camera.sync.exposure_active_output", "other than the trigger input"});
}

// Fields each valid alone that contradict each other, or the LEDs: refused naming the field.
TEST(Stage, SettingsThatContradictTheLedsAreRefusedNamingTheField) {
  const std::string led0 =
      R"({"id": 0, "direction": [0, 1, 0], "gpio": {"chip": "gpiochip0", "line": 4}})";
  const std::string led1 =
      R"({"id": 1, "direction": [1, 1, 0], "gpio": {"chip": "gpiochip0", "line": 5}})";
  const std::string leds = R"("leds": [)" + led0 + ", " + led1 + "]";
  // A line-triggered camera with no line to pulse, or with an LED's line.
  ExpectStageError("{" + leds + R"(, "camera": {"sync": {"trigger": "line", "input": "Line0"}}})",
                   {"camera.sync", "\"gpio\"", "\"trigger\": \"line\""});
  ExpectStageError("{" + leds + R"(, "camera": {"sync": {"trigger": "line", "input": "Line0",
                                   "gpio": {"chip": "gpiochip0", "line": 4}}}})",
                   {"camera.sync.gpio", "no LED uses", "LED 0"});
  // The same line on another chip is another line.
  EXPECT_NO_THROW(parse_stage("{" + leds + R"(, "camera": {"sync": {"trigger": "line",
      "input": "Line0", "gpio": {"chip": "gpiochip1", "line": 4}}}})",
                              "ok.json"));
  // Two LEDs in one direction, or driven by one line; a bracket that repeats an exposure or
  // lasts beyond an hour.
  ExpectStageError(
      R"({"leds": [{"id": 0, "direction": [0, 1, 0]}, {"id": 1, "direction": [0, 2, 0]}]})",
      {"leds[1]", "a place of its own", "LED 0"});
  ExpectStageError(R"({"leds": [{"id": 0, "direction": [0, 1, 0], "gpio": {"chip": "c", "line": 4}},
                                {"id": 1, "direction": [1, 0, 0], "gpio": {"chip": "c", "line": 4}}]})",
                   {"leds[1].gpio", "no other LED drives"});
  ExpectStageError("{" + leds + R"(, "camera": {"bracket": [{"exposure_s": 0.01},
                                                            {"exposure_s": 0.005, "gain": 2}]}})",
                   {"camera.bracket[1]", "has not had yet"});
  ExpectStageError("{" + leds + R"(, "camera": {"bracket": [{"exposure_s": 1e9}]}})",
                   {"camera.bracket[0].exposure_s", "at most an hour"});
  // A reference period without a reference LED.
  ExpectStageError("{" + leds + R"(, "plan": {"reference_every": 3}})",
                   {"plan.reference_every", "\"reference_led\""});
  // Simulated dead LEDs: every LED (a field of nothing), one twice, one that is not there.
  ExpectStageError("{" + leds + R"(, "camera": {"simulated_sensor": {"dead_leds": [0, 1]}}})",
                   {"camera.simulated_sensor.dead_leds", "some LED left alive"});
  ExpectStageError("{" + leds + R"(, "camera": {"simulated_sensor": {"dead_leds": [1, 1]}}})",
                   {"camera.simulated_sensor.dead_leds[1]", "once"});
  ExpectStageError("{" + leds + R"(, "camera": {"simulated_sensor": {"dead_leds": [7]}}})",
                   {"camera.simulated_sensor.dead_leds[0]", "id of an LED"});
}

// The files a stage names for the build are there, or the stage is refused naming the field.
TEST(Stage, MissingSideCarFilesAreNamedWithTheirField) {
  testing::TempDir tmp;
  std::ofstream(tmp / "flat.json") << R"({"layout": {"type": "fibonacci", "count": 10},
    "calibration": {"flat_field": "gone.exr"}})";
  std::ofstream(tmp / "table.json") << R"({"layout": {"type": "fibonacci", "count": 10},
    "camera": {"response": {"type": "table", "file": "gone.txt"}}})";
  for (const auto& [file, field] :
       {std::pair<std::string, std::string>{"flat.json", "calibration.flat_field"},
        {"table.json", "camera.response.file"}}) {
    const Stage stage = load_stage(tmp / file);  // Parsing alone does not read side cars.
    try {
      require_stage_files(stage);
      ADD_FAILURE() << file << ": accepted";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(file + ": " + field), std::string::npos) << msg;
      EXPECT_NE(msg.find("not found"), std::string::npos) << msg;
    }
  }
  std::ofstream(tmp / "gone.txt") << "0 0\n";
  EXPECT_NO_THROW(require_stage_files(load_stage(tmp / "table.json")));
}

TEST(Stage, LoadStageNamesAMissingFile) {
  try {
    load_stage("/nonexistent/dome.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dome.json"), std::string::npos);
  }
}

TEST(Stage, ShippedStageFilesLoad) {
  const auto dir = testing::source_dir() / "data" / "stages";
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".json") continue;
    EXPECT_NO_THROW(load_stage(e.path())) << e.path();
    ++n;
  }
  EXPECT_GT(n, 0);
}

}  // namespace
}  // namespace ls
