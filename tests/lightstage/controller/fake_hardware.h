#pragma once
// Deterministic fake LEDs and camera for sequencer and session tests: the frame value encodes which
// LED is on and the exposure, so tests can check what was captured when.
#include <set>
#include <stdexcept>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/hardware.h"

namespace ls::testing {

class FakeLights : public LightController {
 public:
  explicit FakeLights(int n) : on_(n, false) {}
  int num_lights() const override { return int(on_.size()); }
  void set_light(int i, bool on) override {
    on_.at(i) = on;
    if (on) ++switch_ons;
    max_on = std::max(max_on, count_on());
  }
  void all_off() noexcept override {
    std::fill(on_.begin(), on_.end(), false);
    ++all_off_calls;
  }
  int count_on() const { return int(std::count(on_.begin(), on_.end(), true)); }
  int lit() const {
    for (size_t i = 0; i < on_.size(); ++i) {
      if (on_[i]) return int(i);
    }
    return -1;
  }
  std::vector<bool> on_;
  int switch_ons = 0, all_off_calls = 0, max_on = 0;
};

class FakeCamera : public Camera {
 public:
  explicit FakeCamera(const FakeLights& lights) : lights_(lights) {}
  CameraInfo info() const override { return {"fake", "fake", 8, 4, 3, 12}; }
  CapturedFrame capture(const FrameRequest& r) override {
    ++calls;
    if (timeouts_left > 0 && r.sequence_key == timeout_key) {
      --timeouts_left;
      throw CameraTimeout("fake camera: no frame within 0.1 s");
    }
    if (fail_after >= 0 && frames >= fail_after) throw CameraTimeout("fake camera: unplugged");
    ++frames;
    CapturedFrame f;
    f.raw = {8, 4, 3, 12, std::vector<uint16_t>(8 * 4 * 3)};
    const int lit = lights_.lit();
    const bool dead = dead_leds.count(lit) > 0;
    for (size_t i = 0; i < f.raw.pixels.size(); ++i) {
      // Dark level 50 DN; a lit LED adds 100 + 10 * index DN per 10 ms of exposure.
      const double signal = (lit >= 0 && !dead) ? (100 + 10 * lit) * r.exposure_s / 0.01 : 0;
      f.raw.pixels[i] = uint16_t(std::min(4095.0, 50 + signal + (i % 3)));
    }
    f.exposure_s = r.exposure_s;
    f.gain = r.gain;
    return f;
  }
  const FakeLights& lights_;
  int calls = 0, frames = 0;
  uint64_t timeout_key = 0;
  int timeouts_left = 0;
  int fail_after = -1;
  std::set<int> dead_leds;
};

}  // namespace ls::testing
