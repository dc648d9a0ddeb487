// The frames a session's plan holds (lightstage/session.h): their names on disk and their order.
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "lightstage/session.h"

namespace ls {
namespace {

// Stable id of a frame in the plan; the simulator seeds its noise with it.
uint64_t sequence_key(const FrameKey& k) {
  return ((uint64_t(k.time_step) * 65536u + uint64_t(k.led_index + 1)) * 64u +
          uint64_t(k.exposure_index)) *
             256u +
         uint64_t(k.repeat);
}

}  // namespace

std::string FrameKey::name(const Stage& stage) const {
  char buf[64];
  if (is_dark()) {
    std::snprintf(buf, sizeof buf, "t%03d_dark_e%d_r%d", time_step, exposure_index, repeat);
  } else {
    std::snprintf(buf, sizeof buf, "t%03d_led%03d_e%d", time_step, stage.leds[led_index].id,
                  exposure_index);
    if (repeat > 0) std::snprintf(buf + std::strlen(buf), 16, "_ref%d", repeat);
  }
  return buf;
}

std::vector<PlannedFrame> plan_frames(const Stage& stage) {
  std::vector<PlannedFrame> plan;
  const auto order = stage.capture_order();
  const int steps = int(stage.camera.bracket.size());
  for (int t = 0; t < stage.plan.time_steps; ++t) {
    const double scene_time_s = stage.plan.step_time_s(t);
    auto add = [&](int led, int e, int r) {
      PlannedFrame f;
      f.key = {t, led, e, r};
      f.request.exposure_s = stage.camera.bracket[e].exposure_s;
      f.request.gain = stage.camera.bracket[e].gain;
      f.request.sequence_key = sequence_key(f.key);
      f.request.scene_time_s = scene_time_s;
      plan.push_back(f);
    };
    for (int e = 0; e < steps; ++e) {
      for (int r = 0; r < stage.plan.dark_frames; ++r) add(-1, e, r);
    }
    // The reference LED's shots: before LED 0, N, 2N, ... of the order, and after the last.
    const int reference = stage.led_index(stage.plan.reference_led);
    int shot = 0;
    for (size_t j = 0; j < order.size(); ++j) {
      if (reference >= 0 && j % size_t(stage.plan.reference_every) == 0) {
        ++shot;
        for (int e = 0; e < steps; ++e) add(reference, e, shot);
      }
      for (const int e : stage.exposures_of(order[j])) add(order[j], e, 0);
    }
    if (reference >= 0) {
      ++shot;
      for (int e = 0; e < steps; ++e) add(reference, e, shot);
    }
  }
  return plan;
}

}  // namespace ls
