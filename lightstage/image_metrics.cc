#include "lightstage/image_metrics.h"

#include <algorithm>
#include <cmath>

namespace ls {

ImageError compare_images(const Image& actual, const Image& reference, const Image* mask) {
  ImageError e;
  if (actual.width != reference.width || actual.height != reference.height ||
      actual.channels != reference.channels) {
    e.rmse = e.relative_rmse = e.max_abs = INFINITY;
    return e;
  }
  double sum_sq = 0, sum_ref_sq = 0, peak = 0;
  size_t n = 0;
  for (int y = 0; y < actual.height; ++y) {
    for (int x = 0; x < actual.width; ++x) {
      if (mask && mask->at(x, y, 0) == 0.0f) continue;
      for (int c = 0; c < actual.channels; ++c) {
        const double a = actual.at(x, y, c), b = reference.at(x, y, c);
        const double d = std::isfinite(a) ? a - b : INFINITY;
        sum_sq += d * d;
        sum_ref_sq += b * b;
        peak = std::max(peak, b);
        ++n;
        if (std::abs(d) > e.max_abs || !std::isfinite(d)) {
          e.max_abs = std::abs(d);
          e.worst_x = x, e.worst_y = y, e.worst_c = c;
        }
      }
    }
  }
  if (n == 0) return e;
  e.rmse = std::sqrt(sum_sq / n);
  const double ref_rms = std::sqrt(sum_ref_sq / n);
  e.relative_rmse = ref_rms > 0 ? e.rmse / ref_rms : e.rmse;
  e.psnr_db = e.rmse > 0 ? 20.0 * std::log10(peak / e.rmse) : INFINITY;
  return e;
}

}  // namespace ls
