#pragma once
// Which noise a fit assumes when it has only the data's own estimate (relight/fit/
// noise_from_data.h). The residuals of a Lambertian fit measure the sensor's noise and some of
// what no model explains on a real surface; a fit weighed and thresholded by that estimate alone
// can give a real object worse normals than no weighting (DiLiGenT's ball: 2.5 degrees against
// 1.7). So the fit is unweighted (a variance independent of the value), at a level that sets its
// shadow threshold and its robust and BIC decisions: the estimate's variance at the median lit
// value times 1, 1/4, 4, 1/16 or 16. Each level is fitted on a thinned sample with every fourth
// light held out, and the one whose fits predict the held-out lights best is kept: the mean
// absolute error of the luminance over the fitted pixels' unsaturated held-out samples, in field
// units, so that no candidate is judged by its own noise.
#include <string>
#include <vector>

#include "capture/field.h"
#include "relight/fit/fit.h"

namespace ls::relight {

// "unweighted, the estimate's variance at the median lit value x0.25 (held-out error 0.00176,
// best of 5)": candidate `index` (in the order choose_noise_by_held_out_lights makes them).
std::string describe_noise_choice(int index, double held_out_error);

struct NoiseCandidate {
  NoiseModel model;
  double held_out_error = 0;  // Mean |luminance - model's|, field units.
  long held_out_samples = 0;
};

struct NoiseChoice {
  std::vector<NoiseCandidate> candidates;
  int chosen = 0;  // Index into candidates.
  const NoiseCandidate& best() const { return candidates[size_t(chosen)]; }
  std::string describe() const { return describe_noise_choice(chosen, best().held_out_error); }
};

// `sample`: pixels of the field (rows spread over the object), at least a few hundred lit.
// `options`: the fit's options; its noise is replaced by each candidate in turn, and the sample
// fitted per pixel. The estimate's own level comes first: ties keep it.
NoiseChoice choose_noise_by_held_out_lights(const capture::ReflectanceField& sample,
                                            const FitOptions& options, const NoiseModel& estimate);

}  // namespace ls::relight
