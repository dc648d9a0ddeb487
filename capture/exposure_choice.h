#pragma once
// Exposures chosen per LED: from a session that shot every LED at the whole bracket
// (the last session of the same scene), the fewest bracket steps that keep each pixel's best
// exposure. A pixel's best step is its longest unsaturated one (the HDR merge leans on it: it has
// the most signal above the read noise); a step is kept for an LED when it is the best one for
// more than 1 - coverage of the pixels that LED lights, and so is the shortest step any pixel
// needs (without it, a highlight would clip in every step left). An LED whose light spans a narrow
// range (grazing, behind the backdrop, or on matte surfaces only) then needs one step, not the
// bracket.
#include <map>
#include <vector>

#include "capture/hdr_merge.h"
#include "lightstage/session.h"

namespace ls::capture {

struct ExposureChoice {
  std::map<int, std::vector<int>> led_exposures;       // By LED id: CapturePlan::led_exposures.
  int frames_before = 0, frames_after = 0;             // LED frames per time step.
  double exposure_s_before = 0, exposure_s_after = 0;  // Their summed exposure times.
};

// From time step `time_step` of `previous` (which must hold every LED's whole bracket there:
// InputError naming the first frame missing). A response still to be recovered is taken as linear.
ExposureChoice choose_led_exposures(const Session& previous, int time_step = 0,
                                    double coverage = 0.999, const MergeOptions& merge = {});

}  // namespace ls::capture
