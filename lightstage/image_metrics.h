#pragma once
// Error of an image against a reference, as reported by tests, the demo and the benchmarks.
#include "lightstage/image.h"

namespace ls {

struct ImageError {
  double rmse = 0;           // Over all compared pixels and channels.
  double relative_rmse = 0;  // rmse / rms(reference).
  double psnr_db = 0;        // 20 log10(max(reference) / rmse).
  double max_abs = 0;
  int worst_x = -1, worst_y = -1, worst_c = -1;
};

// Compares where `mask` (optional, 1 channel) is non-zero. Sizes must match (infinite error if
// not).
ImageError compare_images(const Image& actual, const Image& reference, const Image* mask = nullptr);

}  // namespace ls
