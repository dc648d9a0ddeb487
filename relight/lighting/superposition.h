#pragma once
// The superposition check: light is additive, so a photograph of the dome playing LED
// levels must equal the field relit with those levels. It tests the LED calibration as the field
// holds it, the HDR merge and the relighting in one number, and finds what changed since the
// field was captured (an LED dimmed, knocked or failed).
#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <vector>

#include "capture/field.h"
#include "capture/played_photo.h"

namespace ls::relight {

// The field relit with each light's RGB irradiance `weight_rgb` (one per field light; radiance =
// sum_l weight_l * R_l(x) / gain_l(x)), its variance from the field's noise model, and where it
// can be trusted (1 channel: 0 where a weighted light is saturated in the field). gain_l(x) is
// what the build divided the light's image by at pixel x (a near LED's falloff to the reference
// point, its flat field: build_field.h), so that the relit field holds the light the camera saw;
// `pixel_gain` (light, x, y) gives it, empty: 1.
struct PlayedRelit {
  Image radiance, variance, usable;
};
using PixelGain = std::function<float(int light, int x, int y)>;
PlayedRelit relight_played(const capture::ReflectanceField& field,
                           const std::vector<Eigen::Vector3f>& weight_rgb,
                           const PixelGain& pixel_gain = {});

struct SuperpositionCheck {
  double psnr_db = 0;        // Photograph against the relit field, peak the relit's maximum.
  double relative_rmse = 0;  // Over the pixels both trust.
  // Mean over 8 x 8 blocks and channels of (photo - relit)^2 / (variance of the difference) of
  // the block means: about 1 when they agree within their noise, far above when they do not.
  double reduced_chi2 = 0;
  double gain = 0;  // sum(photo * relit) / sum(relit^2): how much brighter the photograph is.
  int blocks = 0;   // Blocks compared (where the played light reaches the view; 0: nowhere).
  // Blocks (and channels) whose difference lies beyond 6 times the spread the blocks show
  // (noise_scale, robust: 1.4826 MAD of their z-scores, at least 1).
  int outlying_blocks = 0;
  double noise_scale = 1.0;

  // The photograph is not the relit field: brighter or dimmer by more than gain_tolerance, or
  // differing in part of the view (outlying blocks: at least 2 and 1% of them).
  bool disagrees(double gain_tolerance) const {
    if (blocks == 0) return false;  // The light played does not reach the view: nothing to test.
    return std::abs(gain - 1) > gain_tolerance ||
           (outlying_blocks >= 2 && outlying_blocks >= 0.01 * 3 * blocks);
  }
};
SuperpositionCheck compare_played(const capture::PlayedPhoto& photo, const PlayedRelit& relit);

}  // namespace ls::relight
