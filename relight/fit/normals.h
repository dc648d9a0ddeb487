#pragma once
// Photometric-stereo normals from a reflectance field (Woodham 1980), plain and robust.
//
// The field holds R(x, l) = f_r * cos(theta_l) * V per unit LED irradiance. For a Lambertian pixel
// R = (albedo / pi) * max(0, n . l), so on the luminance Y the unknowns g = (albedo_Y / pi) * n
// solve the linear system L g = Y over the lit samples (L: one light direction per row). Everything
// is weighted by the measurement noise model below. With near LEDs (positions in the field), each
// pixel's rows of L are its own directions toward the LEDs (capture::PixelLightDirs).
#include <string>

#include "capture/field.h"
#include "lightstage/image.h"

namespace ls::relight {

// Per-sample noise of a field value v (one channel): sigma^2 = a + b * max(v, 0).
// a: the floor (read noise, quantisation, dark-frame noise), b: shot noise (variance grows with the
// signal). The defaults describe a 12-bit camera near mid exposure with R in "relative camera"
// units (diffuse white ~ 0.25): sigma = 1e-3 at black, about 2% at v = 0.2. Measure a and b on
// your camera (dark-frame variance and a flat-field photon-transfer curve) for real data.
struct NoiseModel {
  double a = 1e-6;
  double b = 1e-4;
  double variance(double v) const { return a + b * (v > 0 ? v : 0.0); }
  // The same model as a field records it (read_variance = a, shot_variance_per_unit = b), for
  // simulated fields (sim/noisy_field.h); not marked measured.
  capture::FieldNoise as_field_noise() const {
    capture::FieldNoise noise;
    noise.read_variance = a;
    noise.shot_variance_per_unit = b;
    return noise;
  }
};

enum class NormalMethod {
  // Weighted least squares over every valid light whose sample is above the shadow threshold.
  kLeastSquares,
  // The same, then robust to specular highlights and penumbrae: an initial fit without the
  // brightest
  // `trim_bright_fraction` of the lit samples, then Tukey-biweight IRLS on the residuals (scale
  // from
  // their MAD, never below the noise). Why trimmed start + Tukey rather than Huber: a highlight is
  // a gross outlier (often 10-100x the diffuse value) that Huber only down-weights linearly and so
  // still tilts the normal toward the mirror direction; Tukey gives it weight zero, and the trimmed
  // start puts IRLS in the basin where the highlight has a large residual in the first place.
  kRobust,
};

struct NormalOptions {
  NormalMethod method = NormalMethod::kRobust;
  NoiseModel noise;
  // A sample is "shadowed" (not used) when its luminance is below
  // max(shadow_sigmas * sqrt(noise.a), shadow_fraction * brightest luminance of the pixel).
  double shadow_sigmas = 4.0;
  double shadow_fraction = 0.01;
  int min_lights = 4;  // Fewer usable lights: flagged kTooFewLights.
  // Samples at their light's saturation ceiling (FieldLight::saturates_at, capture/field.h) are
  // lower bounds, not measurements: they are left out like shadowed ones. A pixel that loses more
  // than this fraction of its lit samples so is flagged kSaturated: what remains are the dim,
  // grazing samples, which pin the normal down poorly once the surface is not Lambertian.
  double max_saturated_fraction = 0.75;
  double min_condition = 0.05;         // sqrt(lambda_min / lambda_max) of L^T W L; below: flagged.
  double trim_bright_fraction = 0.15;  // kRobust: brightest lit samples left out of the start.
  int irls_iterations = 4;             // kRobust.
  double tukey_c = 4.685;              // kRobust: Tukey constant, in robust-scale units.

  // Empty when valid; otherwise a sentence naming the option and its valid range.
  std::string validate() const;
};

// Bit codes in NormalMap::flags (0 = ok).
enum NormalFlag : int {
  kNormalOk = 0,
  kTooFewLights = 1,    // Fewer than min_lights valid, unshadowed samples.
  kIllConditioned = 2,  // The used lights span too narrow a cone (see min_condition).
  kAllShadowed = 4,     // No sample above the noise (background, or black).
  kFacingAway = 8,      // The solution points away from the camera or has albedo <= 0.
  // (16 is kFitFailed, relight/fit/fit.h.)
  kSaturated = 32,  // Saturation censored too many samples (see max_saturated_fraction); also set
                    // with kTooFewLights when censoring is what left too few.
  // (128 is kFitNotConverged, 256 kOwnParameters, 512 kLobeShadowed: relight/fit/fit.h.)
  // Every sample exactly 0: a pixel outside the capture's mask (an import zeroes them) or one no
  // LED reaches. Not a failure: summaries count these apart from the flagged pixels.
  kNoSignal = 1024,
};

struct NormalMap {
  Image normal;  // 3 channels, unit, in the stage frame; (0, 0, 0) where flagged.
  Image albedo;  // 3 channels: Lambertian albedo per channel (R = albedo/pi * cos), >= 0.
  // 1 channel in [0, 1]: 1 / (1 + e / 1 degree), e the normal's standard error predicted from the
  // used lights and the residuals (0.5 at a predicted degree).
  Image confidence;
  Image flags;             // 1 channel: NormalFlag bits, 0 = ok.
  int flagged_pixels = 0;  // With signal, and flagged.
  int empty_pixels = 0;    // kNoSignal.
};

// pixel_stride > 1: only every pixel_stride-th pixel in row-major order is solved (as it would be
// with stride 1); the others are left zero and flagged kNoSignal, and are not counted.
NormalMap estimate_normals(const capture::ReflectanceField& field, const NormalOptions& options,
                           long pixel_stride = 1);

}  // namespace ls::relight
