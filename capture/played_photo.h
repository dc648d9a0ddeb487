#pragma once
// A photograph of the dome playing a pattern of LED levels (LightController::set_levels), as
// `lightstage play` takes it to check the whole chain against the field: an HDR
// bracket, shot twice so that the photograph's own noise is measured, dark-subtracted and merged
// through the camera response into radiance (stage units, like the field relit).
#include <cstdint>
#include <vector>

#include "capture/hdr_merge.h"
#include "capture/response.h"
#include "lightstage/hardware.h"
#include "lightstage/stage.h"

namespace ls::capture {

struct PlayedPhoto {
  Image radiance;  // RGB (a mono camera's value in each), the mean of the two shots.
  Image variance;  // RGB: of `radiance`, per pixel, from the two shots' difference.
  Image usable;    // 1 channel: 1 where a shot had an unsaturated sample, else 0.
  std::vector<double> exposures_s;  // The bracket shot.
  int frames = 0;
};

// Plays `level` (one per LED of the stage) for a bracket whose longest exposure is
// longest_exposure_s (x1/4 and x1/16 below it), each exposure shot twice, then dark frames with
// every LED off. sequence_key_base keeps the frames' keys apart from a capture's and from other
// patterns' (the simulator seeds its noise with them). Every LED is off when it returns or throws.
PlayedPhoto shoot_played_photo(const Stage& stage, LightController& lights, Camera& camera,
                               const ResponseCurve& response, const std::vector<double>& level,
                               double longest_exposure_s, uint64_t sequence_key_base);

}  // namespace ls::capture
