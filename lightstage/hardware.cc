#include "lightstage/hardware.h"

#include "lightstage/errors.h"
#include "lightstage/stage.h"

namespace ls {

void LightController::set_levels(const std::vector<double>& /*level*/) {
  throw HardwareError(
      "this light controller switches LEDs only on or off: it cannot light several at set levels "
      "(to play an environment map, a driver with PWM or timed switching is needed)");
}

void LightController::pulse_trigger() {
  throw HardwareError(
      "camera.sync.trigger \"line\": this light controller has no output wired to the camera's "
      "trigger input");
}

void Camera::set_trigger_line(const std::function<void()>& /*pulse*/) {
  throw HardwareError("camera.sync.trigger \"line\": camera " + info().id +
                      " takes no trigger line (use \"software\")");
}

void wire_trigger(const CameraSpec& spec, LightController& lights, Camera& camera) {
  if (spec.sync.line_triggered()) camera.set_trigger_line([&lights] { lights.pulse_trigger(); });
}

void LightController::check_levels(const std::vector<double>& level, int num_lights,
                                   const std::string& who) {
  if (int(level.size()) != num_lights) {
    throw HardwareError(who + ": set_levels: " + std::to_string(level.size()) + " levels for " +
                        std::to_string(num_lights) + " LEDs");
  }
  for (size_t l = 0; l < level.size(); ++l) {
    if (!(level[l] >= 0 && level[l] <= 1)) {
      throw HardwareError(who + ": set_levels: LED index " + std::to_string(l) +
                          ": expected a level in [0, 1], got " + std::to_string(level[l]));
    }
  }
}

}  // namespace ls
