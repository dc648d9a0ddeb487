#pragma once
// A small simulated sensor for capture/ tests, independent of sim/ so that the merge and the
// response are checked against a camera model written down here in a few lines:
//   x  = radiance * exposure_s * gain                    (normalised exposure, 1 = full scale)
//   e  ~ Poisson(x * full_well_e / gain) + dark current  (electrons)
//   v  = (e + N(0, read_noise_e)) * gain / full_well_e + black_level
//   DN = clamp(round(max_dn * v^(1/gamma)), 0, max_dn)
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "lightstage/image.h"

namespace ls::capture::testing {

struct SyntheticCamera {
  int bit_depth = 12;
  double full_well_e = 20000.0;
  double read_noise_e = 4.0;
  double dark_current_e_per_s = 5.0;
  double black_level = 0.01;
  double gamma = 1.0;  // The camera writes DN/max = v^(1/gamma).
  bool noise = true;

  int max_dn() const { return (1 << bit_depth) - 1; }

  // radiance: width * height * channels values in "full scale per second at gain 1".
  RawFrame shoot(int width, int height, int channels, const std::vector<double>& radiance,
                 double exposure_s, double gain, std::mt19937_64& rng) const {
    RawFrame f;
    f.width = width;
    f.height = height;
    f.channels = channels;
    f.bit_depth = bit_depth;
    f.pixels.resize(size_t(width) * height * channels);
    std::normal_distribution<double> read(0.0, read_noise_e);
    for (size_t i = 0; i < f.pixels.size(); ++i) {
      const double x = radiance[i] * exposure_s * gain;
      double electrons = x * full_well_e / gain + dark_current_e_per_s * exposure_s;
      if (noise) {
        // Clamp the mean to what Poisson can sample; anything that large saturates anyway.
        const double mean = std::min(electrons, 1e9);
        electrons = mean > 0 ? double(std::poisson_distribution<long long>(mean)(rng)) : 0.0;
        electrons += read(rng);
      }
      const double v = std::max(0.0, electrons * gain / full_well_e + black_level);
      const double encoded = std::pow(std::min(v, 1.0), 1.0 / gamma);
      f.pixels[i] = uint16_t(std::clamp<long>(std::lround(encoded * max_dn()), 0, max_dn()));
    }
    return f;
  }
};

}  // namespace ls::capture::testing
