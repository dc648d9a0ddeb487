#pragma once
// Leave-lights-out evaluation of compact fields; the simulated RTI scenes it runs on in
// tests and in `lightstage bench compact` are in sim/rti_scenes.h.
//
// Protocol: hold out every `every`-th valid LED (those with index % every == offset), build the
// representation from the others, relight it under a unit point light at each held-out LED's
// direction, and compare with the held-out image (the field's own samples: for a simulated scene
// with noise, they carry the noise too). PSNR is over all held-out images together, with the peak
// = the largest reference value; SSIM is the mean over held-out images and channels of the
// standard SSIM (Wang et al. 2004: 11x11 Gaussian window, sigma 1.5, K1 = 0.01, K2 = 0.03) with
// the same peak as dynamic range.
#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/image.h"
#include "lightstage/stage.h"
#include "relight/lighting/compact_field.h"

namespace ls::evaluation {

// Mean SSIM over the channels of two same-size images, with `peak` as the dynamic range.
double ssim(const Image& actual, const Image& reference, double peak);

struct LeaveLightsOutOptions {
  int every = 5;  // Hold out LEDs with index % every == offset.
  int offset = 2;
  // Held-out LEDs must also have dir.z above this (RTI bases only know the camera's hemisphere).
  double min_dir_z = -1.0;
  // The 8-bit sRGB PSNR's gain: display units (white = 1) per field unit; 0: the brightest
  // held-out sample is white. An imported 8-bit set: 1, its own codes.
  double display_gain = 0.0;
  // Called with the representation built from the training LEDs (e.g. to time its relighting).
  std::function<void(const relight::CompactField&)> inspect;
};

struct LeaveLightsOutResult {
  std::string name;
  double psnr_db = 0;
  // Over the 8-bit sRGB codes of display_gain x both images (peak 255), as the RTI community
  // compares (relight's figures): where the eye sees the error, not where the light is.
  double psnr_srgb8_db = 0;
  double ssim = 0;
  double bytes_per_pixel = 0;
  double build_s = 0;
  int held_out = 0;
  int training = 0;
};

using CompactBuilder =
    std::function<std::unique_ptr<relight::CompactField>(const capture::ReflectanceField&)>;

LeaveLightsOutResult leave_lights_out(const capture::ReflectanceField& field,
                                      const CompactBuilder& build,
                                      const LeaveLightsOutOptions& options = {});

}  // namespace ls::evaluation
