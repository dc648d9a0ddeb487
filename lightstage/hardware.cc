#include "lightstage/hardware.h"

#include "lightstage/errors.h"

namespace ls {

void LightController::set_levels(const std::vector<double>& /*level*/) {
  throw HardwareError(
      "this light controller switches LEDs only on or off: it cannot light several at set levels "
      "(to play an environment map, a driver with PWM or timed switching is needed)");
}

}  // namespace ls
