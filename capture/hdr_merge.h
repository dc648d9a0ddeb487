#pragma once
// HDR merge of one bracket with dark subtraction. For each pixel and channel:
//   signal_k = (response^-1(DN_k) - response^-1(dark_k)) / (exposure_k * gain_k)
//   merged   = sum_k w_k * signal_k / sum_k w_k
// with w_k a hat weight on the normalised linear value that is 0 at saturation and small near the
// noise floor, times exposure_k * gain_k (longer exposures carry more photons, less relative
// noise). OpenCV's MergeDebevec handles 8-bit input only and does no dark subtraction, hence this
// loop.
#include <vector>

#include "capture/response.h"
#include "lightstage/image.h"

namespace ls::capture {

struct BracketFrame {
  const RawFrame* raw = nullptr;
  const Image* dark_linear = nullptr;  // Mean dark frame for this step, already linearised.
  double exposure_s = 0.0;
  double gain = 1.0;
};

struct MergeOptions {
  double saturation_level =
      0.98;                    // Normalised linear value at and above which a sample is unusable.
  double floor_level = 0.002;  // Below this, weight ramps down (read noise dominates).
};

// Returns the merged signal in "full scale per second at gain 1" per channel, plus a 4th channel
// holding the number of usable samples (0 = every exposure saturated: value is a lower bound taken
// from the shortest exposure).
Image merge_bracket(const std::vector<BracketFrame>& bracket, const ResponseCurve& response,
                    const MergeOptions& options = {});

// Linearised mean of dark frames (response^-1 applied per frame, then averaged).
Image mean_dark(const std::vector<const RawFrame*>& darks, const ResponseCurve& response);

}  // namespace ls::capture
