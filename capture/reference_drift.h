#pragma once
// How the dome's output drifted during a time step, from the reference LED's shots
// (CapturePlan::reference_led): the same LED, the same bracket, shot again every N LEDs. Its
// signal relative to its first shot of the step is the drift of everything between the LED driver
// and the camera (LED temperature, supply, gain); the build can divide it out of every LED.
#include <optional>
#include <string>
#include <vector>

#include "capture/response.h"
#include "lightstage/session.h"

namespace ls::capture {

struct ReferenceDrift {
  int time_step = 0;
  // Where each shot was taken in the step's capture order: before LED position 0, N, 2N, ...;
  // the last after every LED (the number of LEDs).
  std::vector<double> positions;
  std::vector<double> output;  // Relative to the step's first shot (1 = no drift).
  int exposure_index = 0;      // The bracket step it was measured on (most unsaturated signal).

  // The output while the LED at `position` in the capture order was shot (its slot's middle,
  // position + 0.5), interpolated between the shots around it.
  double output_at_led(int position) const;
  double largest_change() const;                   // Max |output - 1|.
  std::string describe(const Stage& stage) const;  // One line for the operator.
};

// The reference LED's output at each of its shots of `time_step`: linear signal above the mean
// dark frame, summed over the pixels unsaturated in every shot, on the bracket step with the most
// such signal. nullopt when the plan has no reference LED; InputError naming the frame when a shot
// of the step is missing.
std::optional<ReferenceDrift> measure_reference_drift(const Session& session, int time_step,
                                                      const ResponseCurve& response);

// measure_reference_drift for the build: a drift beyond 0.5%, or a missing shot, is reported in
// `warnings`, and the drift returned only when `correct` (to be divided out of every LED).
std::optional<ReferenceDrift> build_drift(const Session& session, int time_step,
                                          const ResponseCurve& response, bool correct,
                                          std::vector<std::string>* warnings);

}  // namespace ls::capture
