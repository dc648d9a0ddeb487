#pragma once
// A small stage on the Aravis fake camera for back-end and fault tests, and what an error said.
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "lightstage/stage.h"

namespace ls::testing {

inline Stage FakeAravisStage(int leds = 4) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(leds, 0));
  stage.name = "aravis-fake";
  stage.source = "fake_stage.json";
  for (int i = 0; i < leds; ++i) {
    stage.leds[i].gpio_chip = "gpiochip-lightstage-absent";
    stage.leds[i].gpio_line = i;
  }
  stage.camera.backend = "aravis";
  stage.camera.device_id = "Fake_1";
  stage.camera.width = 32;
  stage.camera.height = 24;
  stage.camera.channels = 1;
  stage.camera.bit_depth = 8;
  stage.camera.bracket = {{0.001, 1.0}, {0.004, 1.0}};
  stage.camera.timeout_s = 2.0;
  stage.camera.retries = 1;
  stage.plan.dark_frames = 1;
  return stage;
}

// The message of the `Error` that `f` throws (a test failure when it throws none).
template <typename Error>
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an error";
  return {};
}

}  // namespace ls::testing
