#pragma once
// A session's frames by LED for one time step (capture/build_field.h), and the camera response
// recovered from them.
#include <algorithm>
#include <vector>

#include "capture/response.h"
#include "lightstage/session.h"

namespace ls::capture {

// One LED's bracket in this time step: a record per exposure step, null where the frame is absent
// (or not planned: Stage::exposures_of).
struct LedFrames {
  int led_index = -1;
  std::vector<const FrameRecord*> records;
  std::vector<bool> planned;  // Per exposure step: whether the plan shoots this LED at it.
  // Every planned frame is there.
  bool complete() const {
    for (size_t e = 0; e < records.size(); ++e) {
      if (planned[e] && records[e] == nullptr) return false;
    }
    return true;
  }
  // Every step of the bracket is there (photon transfer and response recovery need them all).
  bool full() const {
    return std::all_of(records.begin(), records.end(), [](auto* r) { return r != nullptr; });
  }
};

// Time step t's frames: each LED of `order`'s bracket (in that order, the frames it is planned at),
// and the keys of the dark frames per exposure step.
std::vector<LedFrames> index_led_frames(const Session& session, int time_step,
                                        const std::vector<int>& order,
                                        std::vector<std::vector<FrameKey>>* dark_keys);

// The linear mean of time step t's dark frames at bracket step e (hdr_merge.h mean_dark); an empty
// image when the session has none.
Image session_mean_dark(const Session& session, int time_step, int exposure_index,
                        const ResponseCurve& response);

// The response recovered (kRecover) from the brackets of the few brightest usable LEDs, their
// frames side by side; InputError when no LED has a complete bracket.
ResponseCurve recover_from_session(const Session& session, const std::vector<LedFrames>& brackets,
                                   const std::vector<bool>& usable);

}  // namespace ls::capture
