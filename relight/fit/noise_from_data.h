#pragma once
// The noise of a field that carries no measured noise (an imported RTI or DiLiGenT set
// has no dark frames and no bracket), estimated from the data itself: the residuals of a robust
// Lambertian photometric-stereo fit. Each pixel's samples lit well above its terminator
// (n.l >= 0.3) are compared with albedo * n.l / pi; the residuals are binned by that predicted
// value (in field units), each bin's variance is taken robustly (1.4826 MAD, squared, so that
// highlights and shadows the Lambertian model does not explain stay out) and scaled by n / (n - 3)
// for the three parameters each pixel's fit took from its own samples; variance = a + b v is then
// fitted to the bins by weighted least squares, a and b >= 0, a no lower than the rounding of one
// code step at black (the lights' smallest positive values: the quantisation of 8-bit sets).
// Saturated and non-finite samples are left out, as the normals leave them. The variance of a value
// is what NoiseModel means: the field's own units, per sample.
#include <optional>
#include <string>

#include "capture/field.h"
#include "relight/fit/normals.h"

namespace ls::relight {

struct DataNoise {
  NoiseModel model;
  long samples = 0;              // Residuals used.
  int pixels = 0;                // Pixels they came from.
  std::string describe() const;  // For noise_source: how it was estimated, from how much.
};

// From `field` (the whole field, or a band of its rows), starting from options.noise and fitting
// again with each estimate until it settles. nullopt when fewer than 100 pixels or 2,000 residuals
// remain (too few lit pixels to say).
std::optional<DataNoise> noise_from_data(const capture::ReflectanceField& field,
                                         const NormalOptions& options);

}  // namespace ls::relight
