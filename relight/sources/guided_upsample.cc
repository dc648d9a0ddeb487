#include "relight/sources/guided_upsample.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "lightstage/errors.h"

namespace ls::relight {

namespace {

constexpr double kGuideDarkShare = 0.03;  // e, the dark floor, as a share of the guide's mean.

// Where a full-size coordinate falls between the reduced image's pixel centres.
struct Between {
  int lo = 0, hi = 0;
  float t = 0;  // Weight of hi.
};
Between between(int x, int factor, int reduced) {
  const float at = (float(x) + 0.5f) / float(factor) - 0.5f;
  Between b;
  b.lo = std::clamp(int(std::floor(at)), 0, reduced - 1);
  b.hi = std::min(b.lo + 1, reduced - 1);
  b.t = std::clamp(at - float(b.lo), 0.0f, 1.0f);
  return b;
}

float bilinear(const Image& image, const Between& bx, const Between& by, int c) {
  const float top = (1 - bx.t) * image.at(bx.lo, by.lo, c) + bx.t * image.at(bx.hi, by.lo, c);
  const float bottom = (1 - bx.t) * image.at(bx.lo, by.hi, c) + bx.t * image.at(bx.hi, by.hi, c);
  return (1 - by.t) * top + by.t * bottom;
}

}  // namespace

void add_guided_upsample(const Image& low, const Image& guide_low, const Image& guide, int factor,
                         Image& out) {
  LS_CHECK(factor >= 1 && low.channels == 3 && guide_low.channels == 3 && guide.channels == 3 &&
               out.channels == 3,
           "guided upsample: 3-channel images and a factor >= 1");
  LS_CHECK(guide_low.width == low.width && guide_low.height == low.height &&
               guide.width == out.width && guide.height == out.height &&
               low.width == (out.width + factor - 1) / factor &&
               low.height == (out.height + factor - 1) / factor,
           "guided upsample: a " + std::to_string(low.width) + "x" + std::to_string(low.height) +
               " image is not a " + std::to_string(out.width) + "x" + std::to_string(out.height) +
               " one reduced by " + std::to_string(factor));
  std::array<double, 3> mean{};
  for (std::size_t p = 0; p < guide_low.num_pixels(); ++p) {
    for (int c = 0; c < 3; ++c) mean[size_t(c)] += std::max(0.0f, guide_low.pixels[3 * p + c]);
  }
  std::array<float, 3> floor{};
  for (int c = 0; c < 3; ++c) {
    floor[size_t(c)] =
        float(std::max(kGuideDarkShare * mean[size_t(c)] / double(guide_low.num_pixels()), 1e-30));
  }
  const float most = float(factor) * float(factor);
  std::vector<Between> columns(size_t(out.width));  // The same for every row.
  for (int x = 0; x < out.width; ++x) columns[size_t(x)] = between(x, factor, low.width);
  tbb::parallel_for(0, out.height, [&](int y) {
    const Between by = between(y, factor, low.height);
    for (int x = 0; x < out.width; ++x) {
      const Between& bx = columns[size_t(x)];
      for (int c = 0; c < 3; ++c) {
        const float e = floor[size_t(c)];
        const float ratio = (std::max(0.0f, guide.at(x, y, c)) + e) /
                            (std::max(0.0f, bilinear(guide_low, bx, by, c)) + e);
        out.at(x, y, c) += bilinear(low, bx, by, c) * std::min(ratio, most);
      }
    }
  });
}

}  // namespace ls::relight
