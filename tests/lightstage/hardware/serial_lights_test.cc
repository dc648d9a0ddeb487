// LEDs on a serial board, over a pseudo-terminal pair with the board emulator at the far end: the
// lsled1 protocol as the board sees it, and boards that stop answering or answer garbage.
#include "lightstage/hardware/serial_lights.h"

#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <mutex>

#include "lightstage/errors.h"
#include "sim/led_board_emulator.h"
#include "tests/lightstage/hardware/hardware_stage.h"

namespace ls {
namespace {

// What the board drove: each channel's last level, and how many times everything went off.
struct BoardOutputs {
  std::mutex mutex;
  std::map<int, double> level;
  int all_off = 0;
};

struct Rig {
  BoardOutputs outputs;
  sim::LedBoardEmulator board;
  Stage stage;

  explicit Rig(int channels = 8, int leds = 4)
      : board(
            channels,
            [this](int c, double l) {
              const std::lock_guard lock(outputs.mutex);
              outputs.level[c] = l;
            },
            [this] {
              const std::lock_guard lock(outputs.mutex);
              outputs.level.clear();
              ++outputs.all_off;
            }),
        stage(stage_with_directions(fibonacci_dome_directions(leds, 0))) {
    stage.source = "dome.json";
    stage.led_driver.backend = "serial";
    stage.led_driver.port = board.port();
    stage.led_driver.timeout_s = 0.2;
    stage.led_driver.startup_s = 0.5;
  }

  double level(int channel) {
    const std::lock_guard lock(outputs.mutex);
    return outputs.level.count(channel) ? outputs.level[channel] : 0.0;
  }
};

std::string hardware_error(const std::function<void()>& f) {
  return testing::error_of<HardwareError>(f);
}

TEST(SerialLights, SwitchesTheBoardsChannelsAsTheStageWiresThem) {
  Rig rig;
  rig.stage.leds[2].board_channel = 7;
  SerialLights lights(rig.stage);
  EXPECT_EQ(lights.board_channels(), 8);
  EXPECT_GE(rig.outputs.all_off, 1);  // Everything off before the first LED.
  lights.set_light(2, true);
  EXPECT_EQ(rig.level(7), 1.0);
  lights.set_light(2, false);
  EXPECT_EQ(rig.level(7), 0.0);
  lights.set_light(0, true);
  EXPECT_EQ(rig.level(0), 1.0);
  lights.all_off();
  EXPECT_EQ(rig.level(0), 0.0);
  EXPECT_EQ(lights.describe(2), "LED " + std::to_string(rig.stage.leds[2].id) +
                                    " (board channel 7 on " + rig.board.port() + ")");
}

TEST(SerialLights, LevelsAreSentOnlyWhereTheyChange) {
  Rig rig;
  SerialLights lights(rig.stage);
  const int before = rig.board.commands_seen();
  lights.set_levels({0.25, 0.0, 0.5, 0.0});
  EXPECT_EQ(rig.board.commands_seen() - before, 2);
  EXPECT_DOUBLE_EQ(rig.level(0), 0.25);
  EXPECT_DOUBLE_EQ(rig.level(2), 0.5);
  lights.set_levels({0.25, 0.0, 1.0, 0.0});
  EXPECT_EQ(rig.board.commands_seen() - before, 3);
  EXPECT_THROW(lights.set_levels({2.0, 0, 0, 0}), HardwareError);
}

TEST(SerialLights, ASilentBoardIsAnErrorNamingThePortAndTheCommand) {
  Rig rig;
  rig.board.set_behaviour(sim::LedBoardEmulator::Behaviour::kSilent);
  const auto start = std::chrono::steady_clock::now();
  const std::string what = hardware_error([&] { SerialLights lights(rig.stage); });
  EXPECT_NE(what.find(rig.board.port()), std::string::npos) << what;
  EXPECT_NE(what.find("no answer to 'ID'"), std::string::npos) << what;
  EXPECT_NE(what.find("led_driver.startup_s"), std::string::npos) << what;
  // It gave up after startup_s, not at once and not forever.
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(waited, rig.stage.led_driver.startup_s);
}

TEST(SerialLights, ABoardThatGoesSilentMidCaptureNamesTheLed) {
  Rig rig;
  SerialLights lights(rig.stage);
  lights.set_light(1, true);
  rig.board.set_behaviour(sim::LedBoardEmulator::Behaviour::kSilent);
  const std::string what = hardware_error([&] { lights.set_light(1, false); });
  EXPECT_NE(what.find("LED " + std::to_string(rig.stage.leds[1].id) + " (board channel 1 on " +
                      rig.board.port() + ")"),
            std::string::npos)
      << what;
  EXPECT_NE(what.find("no answer to 'SET 1 0'"), std::string::npos) << what;
  lights.all_off();  // Must not throw, even to a silent board.
}

TEST(SerialLights, GarbageIsNotTakenForAnAnswer) {
  Rig rig;
  rig.board.set_behaviour(sim::LedBoardEmulator::Behaviour::kGarbage);
  const std::string at_start = hardware_error([&] { SerialLights lights(rig.stage); });
  EXPECT_NE(at_start.find("answered '\\x7f~\\x03#K\\xfe' to 'ID'"), std::string::npos) << at_start;

  rig.board.set_behaviour(sim::LedBoardEmulator::Behaviour::kAnswers);
  SerialLights lights(rig.stage);
  rig.board.change_after(1, sim::LedBoardEmulator::Behaviour::kGarbage);
  lights.set_light(3, true);
  const std::string mid = hardware_error([&] { lights.set_light(3, false); });
  EXPECT_NE(mid.find("not an lsled1 board?"), std::string::npos) << mid;
}

TEST(SerialLights, ABoardWithTooFewChannelsOrNoPortIsRefused) {
  Rig small(/*channels=*/2, /*leds=*/4);
  const std::string few = hardware_error([&] { SerialLights lights(small.stage); });
  EXPECT_NE(few.find("the board has only 2 channels (leds[2].channel)"), std::string::npos) << few;

  Stage missing = small.stage;
  missing.led_driver.port = "/dev/lightstage-no-such-board";
  const std::string gone = hardware_error([&] { SerialLights lights(missing); });
  EXPECT_NE(gone.find("LED board on /dev/lightstage-no-such-board (led_driver.port): cannot open"),
            std::string::npos)
      << gone;
}

TEST(SerialLights, TheStageFileNamesTheBoardAndEachLedsChannel) {
  const Stage stage = parse_stage(R"({
    "led_driver": {"backend": "serial", "port": "/dev/ttyACM0", "baud": 57600},
    "leds": [{"direction": [0, 1, 0], "channel": 3}, {"direction": [1, 0, 0]}]})",
                                  "dome.json");
  EXPECT_TRUE(stage.led_driver.serial());
  EXPECT_EQ(stage.led_driver.port, "/dev/ttyACM0");
  EXPECT_EQ(stage.led_driver.baud, 57600);
  EXPECT_EQ(stage.leds[0].board_channel, 3);
  EXPECT_EQ(parse_stage(stage_to_json(stage), "again.json").led_driver.port, "/dev/ttyACM0");
  const auto refused = [](const char* json) {
    try {
      (void)parse_stage(json, "dome.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(refused(R"({"led_driver": {"backend": "serial"}, "leds": [{"direction": [0, 1, 0]}]})")
                .find("dome.json: led_driver: "),
            std::string::npos);
  EXPECT_NE(refused(R"({"led_driver": {"backend": "serial", "port": "/dev/x", "baud": 1234},
                        "leds": [{"direction": [0, 1, 0]}]})")
                .find("led_driver.baud"),
            std::string::npos);
  EXPECT_NE(refused(R"({"leds": [{"direction": [0, 1, 0], "channel": 1},
                                 {"direction": [1, 0, 0]}]})")
                .find("leds[1]: expected a board channel no other LED uses"),
            std::string::npos)
      << refused(R"({"leds": [{"direction": [0, 1, 0], "channel": 1}, {"direction": [1, 0, 0]}]})");
}

}  // namespace
}  // namespace ls
