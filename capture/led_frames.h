#pragma once
// A session's frames by LED for one time step (capture/build_field.h), and the camera response
// recovered from them.
#include <algorithm>
#include <vector>

#include "capture/response.h"
#include "lightstage/session.h"

namespace ls::capture {

// One LED's bracket in this time step: a record per exposure step, null where the frame is absent.
struct LedFrames {
  int led_index = -1;
  std::vector<const FrameRecord*> records;
  bool complete() const {
    return std::all_of(records.begin(), records.end(), [](auto* r) { return r != nullptr; });
  }
};

// The response recovered (kRecover) from the brackets of the few brightest usable LEDs, their
// frames side by side; InputError when no LED has a complete bracket.
ResponseCurve recover_from_session(const Session& session, const std::vector<LedFrames>& brackets,
                                   const std::vector<bool>& usable);

}  // namespace ls::capture
