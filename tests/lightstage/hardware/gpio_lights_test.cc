#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <thread>
#include <utility>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/hardware/gpiod_lights.h"
#include "tests/lightstage/hardware/fake_line_driver.h"

namespace ls {
namespace {

using testing::FakeGpio;
using testing::FakeLineDriver;

// Three LEDs (ids 10, 11, 12) on gpiochip0 lines 4, 5, 6; LED 11 is active-low.
Stage GpioStage() {
  Stage stage = stage_with_directions(fibonacci_dome_directions(3, 0));
  stage.source = "stage.json";
  for (int i = 0; i < 3; ++i) {
    stage.leds[i].id = 10 + i;
    stage.leds[i].gpio_chip = "gpiochip0";
    stage.leds[i].gpio_line = 4 + i;
  }
  stage.leds[1].active_low = true;
  return stage;
}

bool Level(const FakeGpio& gpio, int line) { return gpio.level.at({"gpiochip0", line}); }

TEST(GpioLights, RequestsEveryLineOnceDrivenOffWithItsPolarity) {
  FakeGpio gpio;
  GpioLights lights(GpioStage(), std::make_unique<FakeLineDriver>(gpio));
  EXPECT_EQ(lights.num_lights(), 3);
  EXPECT_EQ(gpio.level.size(), 3u);
  EXPECT_FALSE(Level(gpio, 4));
  EXPECT_TRUE(Level(gpio, 5));  // Active-low: off is high.
  EXPECT_FALSE(Level(gpio, 6));
  EXPECT_EQ(lights.count_on(), 0);
}

TEST(GpioLights, SwitchesTheMappedLineAtTheConfiguredPolarity) {
  FakeGpio gpio;
  GpioLights lights(GpioStage(), std::make_unique<FakeLineDriver>(gpio));
  lights.set_light(1, true);
  EXPECT_FALSE(Level(gpio, 5));  // Active-low on = low.
  EXPECT_FALSE(Level(gpio, 4));
  lights.set_light(1, false);
  lights.set_light(2, true);
  EXPECT_TRUE(Level(gpio, 5));
  EXPECT_TRUE(Level(gpio, 6));
  EXPECT_TRUE(lights.is_on(2));
  EXPECT_EQ(lights.count_on(), 1);
}

TEST(GpioLights, AllOffKeepsGoingPastAFailingLineAndNeverThrows) {
  FakeGpio gpio;
  GpioLights lights(GpioStage(), std::make_unique<FakeLineDriver>(gpio));
  lights.set_light(0, true);
  lights.set_light(2, true);
  gpio.failing_handles = {0};
  static_assert(noexcept(lights.all_off()));
  lights.all_off();
  EXPECT_TRUE(Level(gpio, 4));   // The failing line stays where it was...
  EXPECT_FALSE(Level(gpio, 6));  // ...the others are off.
  EXPECT_TRUE(Level(gpio, 5));
  EXPECT_NE(lights.last_error().find("LED 10 (gpiochip0 line 4"), std::string::npos)
      << lights.last_error();
  EXPECT_TRUE(lights.is_on(0));
  EXPECT_FALSE(lights.is_on(2));
}

TEST(GpioLights, DestructionSwitchesOffAndReleases) {
  FakeGpio gpio;
  {
    GpioLights lights(GpioStage(), std::make_unique<FakeLineDriver>(gpio));
    lights.set_light(0, true);
  }
  EXPECT_TRUE(gpio.level.empty());
  EXPECT_GE(gpio.releases, 1);
}

TEST(GpioLights, SetLightFailureNamesTheLed) {
  FakeGpio gpio;
  GpioLights lights(GpioStage(), std::make_unique<FakeLineDriver>(gpio));
  gpio.failing_handles = {2};
  try {
    lights.set_light(2, true);
    FAIL() << "expected HardwareError";
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find("LED 12 (gpiochip0 line 6"), std::string::npos)
        << e.what();
  }
}

void ExpectHardwareError(FakeGpio& gpio, const Stage& stage, const std::string& needle) {
  try {
    GpioLights lights(stage, std::make_unique<FakeLineDriver>(gpio));
    FAIL() << "expected HardwareError containing " << needle;
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(GpioLights, MissingChipIsAnErrorNamingLedChipAndLine) {
  FakeGpio gpio;
  Stage stage = GpioStage();
  stage.leds[2].gpio_chip = "gpiochip7";
  ExpectHardwareError(gpio, stage, "LED 12 (gpiochip7 line 6");
  EXPECT_TRUE(gpio.level.empty()) << "lines requested before the failure are released";
}

TEST(GpioLights, MissingLineAndBusyLineAreErrors) {
  FakeGpio gpio;
  Stage stage = GpioStage();
  stage.leds[0].gpio_line = 40;
  ExpectHardwareError(gpio, stage, "LED 10 (gpiochip0 line 40");
  gpio.held_by_others[{"gpiochip0", 5}] = "other-daemon";
  ExpectHardwareError(gpio, GpioStage(), "held by \"other-daemon\"");
}

TEST(GpioLights, StageWithoutLinesOrWithSharedLinesIsAnInputError) {
  FakeGpio gpio;
  Stage stage = GpioStage();
  stage.leds[1].gpio_chip.clear();
  EXPECT_THROW(GpioLights(stage, std::make_unique<FakeLineDriver>(gpio)), InputError);
  stage = GpioStage();
  stage.leds[2].gpio_line = 4;
  try {
    GpioLights lights(stage, std::make_unique<FakeLineDriver>(gpio));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("already used by LED 10"), std::string::npos) << e.what();
  }
}

// camera.sync.trigger "line": the trigger line is requested low with the LEDs, and each pulse
// is one rising edge followed by the line low again, pulse_us later.
TEST(GpioLights, TriggerLinePulsesOnceARisingEdgeAndIsCheckedLikeAnLedLine) {
  FakeGpio gpio;
  Stage stage = GpioStage();
  stage.camera.sync.trigger = "line";
  stage.camera.sync.pulse_us = 2000;
  try {
    GpioLights lights(stage, std::make_unique<FakeLineDriver>(gpio));
    FAIL() << "no trigger line given";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("stage.json: camera.sync.gpio"), std::string::npos)
        << e.what();
  }
  stage.camera.sync.gpio_chip = "gpiochip0";
  stage.camera.sync.gpio_line = 5;  // LED 11's.
  EXPECT_THROW(GpioLights(stage, std::make_unique<FakeLineDriver>(gpio)), InputError);
  stage.camera.sync.gpio_line = 40;
  ExpectHardwareError(gpio, stage, "trigger line camera.sync.gpio (gpiochip0 line 40)");
  EXPECT_TRUE(gpio.level.empty()) << "the LEDs' lines, requested first, are released";

  stage.camera.sync.gpio_line = 9;
  GpioLights lights(stage, std::make_unique<FakeLineDriver>(gpio));
  EXPECT_FALSE(Level(gpio, 9));
  std::vector<std::pair<bool, std::chrono::steady_clock::time_point>> edges;
  gpio.wire = [&](const std::pair<std::string, int>& line, bool high) {
    if (line.second == 9) edges.emplace_back(high, std::chrono::steady_clock::now());
  };
  lights.pulse_trigger();
  ASSERT_EQ(edges.size(), 2u);
  EXPECT_TRUE(edges[0].first);
  EXPECT_FALSE(edges[1].first);
  EXPECT_GE(edges[1].second - edges[0].second, std::chrono::milliseconds(2));
  EXPECT_EQ(lights.count_on(), 0);  // No LED moved.
  gpio.wire = nullptr;
  gpio.failing_handles.insert(3);  // The trigger line's handle, after the three LEDs'.
  try {
    lights.pulse_trigger();
    FAIL() << "expected HardwareError";
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find("trigger line camera.sync.gpio (gpiochip0 line 9): "
                                         "cannot pulse"),
              std::string::npos)
        << e.what();
  }
}

// The real libgpiod driver: no GPIO chip exists on CI machines, and no machine has this one.
TEST(GpiodDriver, MissingChipIsAClearHardwareError) {
  Stage stage = GpioStage();
  for (auto& led : stage.leds) led.gpio_chip = "gpiochip-lightstage-absent";
  try {
    GpioLights lights(stage, make_gpiod_line_driver());
    FAIL();
  } catch (const HardwareError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("LED 10 (gpiochip-lightstage-absent line 4"), std::string::npos) << what;
    EXPECT_NE(what.find("cannot be opened"), std::string::npos) << what;
  }
}

TEST(GpiodDriver, ListingChipsNeverThrows) { EXPECT_NO_THROW(list_gpio_chips()); }

TEST(GpioPwm, LevelsRunOnTheirThreadUntilAllOffLeavesEveryLineOff) {
  FakeGpio gpio;
  GpioLights lights(GpioStage(), std::make_unique<FakeLineDriver>(gpio));
  lights.set_pwm_period(0.002);
  EXPECT_DOUBLE_EQ(lights.level_period_s(), 0.002);
  lights.set_levels({0.5, 1.0, 0.0});
  // Wait (at most 10 s, on a loaded machine) until LED 10 has been switched several times.
  for (int waited = 0; gpio.sets < 8 && waited < 10000; ++waited) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_GE(gpio.sets.load(), 8);
  lights.all_off();
  EXPECT_FALSE(Level(gpio, 4));
  EXPECT_TRUE(Level(gpio, 5));   // Active-low: off is high.
  EXPECT_FALSE(Level(gpio, 6));  // Level 0: never on.
  EXPECT_EQ(lights.count_on(), 0);
  const int after = gpio.sets;
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(gpio.sets.load(), after);  // The thread is gone.
  EXPECT_NO_THROW(lights.verify_levels());
  // A new pattern starts from dark: LED 10, on in the old one and off in this, is off.
  lights.set_levels({0.0, 0.0, 1.0});
  lights.set_light(1, false);  // Ends the pattern, every line off, then switches one line.
  EXPECT_FALSE(Level(gpio, 4));
  EXPECT_FALSE(Level(gpio, 6));
  EXPECT_THROW(lights.set_levels({0.5, 2.0, 0.0}), HardwareError);
  EXPECT_THROW(lights.set_levels({0.5}), HardwareError);
}

TEST(GpioPwm, ALineThatFailsStopsThePatternSaysSoAndLeavesTheOthersOff) {
  FakeGpio gpio;
  GpioLights lights(GpioStage(), std::make_unique<FakeLineDriver>(gpio));
  lights.set_pwm_period(0.002);
  gpio.failing_handles = {2};
  lights.set_levels({1.0, 0.5, 1.0});
  for (int waited = 0; waited < 10000; ++waited) {  // At most 10 s on a loaded machine.
    try {
      lights.verify_levels();
    } catch (const HardwareError&) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_THROW(lights.verify_levels(), HardwareError);
  EXPECT_FALSE(Level(gpio, 4));
  EXPECT_TRUE(Level(gpio, 5));  // Active-low: off.
  lights.all_off();
}

}  // namespace
}  // namespace ls
