// Camera response by Robertson et al. (OpenCV photo) next to Debevec-Malik, on the bracket of
// tests/capture's synthetic gamma-2.2 camera (a dense ramp: Robertson has no smoothness term).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "capture/response.h"
#include "tests/capture/synthetic_camera.h"

namespace ls::capture {
namespace {

TEST(Response, RobertsonRecoversGammaCurveLikeDebevec) {
  testing::SyntheticCamera camera;
  camera.gamma = 2.2;
  camera.black_level = 0.0;
  camera.dark_current_e_per_s = 0.0;
  const int width = 1024, height = 24, channels = 3;
  std::vector<double> radiance(size_t(width) * height * channels);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < channels; ++c) {
        radiance[(size_t(y) * width + x) * channels + c] =
            0.9 * std::pow(10.0, -2.5 * x / (width - 1)) * (1.0 - 0.15 * c);
      }
    }
  }
  std::mt19937_64 rng(7);
  const std::vector<double> exposure_s = {1.0 / 64, 1.0 / 16, 1.0 / 4, 1.0, 4.0};
  std::vector<RawFrame> frames;
  for (double t : exposure_s) {
    frames.push_back(camera.shoot(width, height, channels, radiance, t, 1.0, rng));
  }
  std::vector<const RawFrame*> pointers;
  for (const RawFrame& f : frames) pointers.push_back(&f);
  for (const ResponseMethod method : {ResponseMethod::kDebevec, ResponseMethod::kRobertson}) {
    const ResponseCurve r = recover_response(pointers, exposure_s, method);
    double worst_rel_mid = 0;
    for (int c = 0; c < channels; ++c) {
      for (int dn = 410; dn < 4096; ++dn) {  // Above 10% of full scale in DN.
        const double truth = std::pow(dn / 4095.0, 2.2);
        worst_rel_mid = std::max(worst_rel_mid, std::abs(r.to_linear(dn, c) / truth - 1.0));
      }
    }
    std::printf("%s: worst relative error above 10%% DN %.2f%%\n",
                method == ResponseMethod::kDebevec ? "Debevec" : "Robertson", 100 * worst_rel_mid);
    // Measured: Debevec 1.1%, Robertson 20% (broad bumps of +-10-20% between 8-bit values 60
    // and 150; a running mean over the curve does not remove them). Robertson is offered for
    // comparison; Debevec stays the default.
    EXPECT_LT(worst_rel_mid, method == ResponseMethod::kDebevec ? 0.03 : 0.3);
  }
}

}  // namespace
}  // namespace ls::capture
