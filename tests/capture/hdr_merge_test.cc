#include "capture/hdr_merge.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lightstage/errors.h"
#include "tests/capture/synthetic_camera.h"

namespace ls::capture {
namespace {

using testing::SyntheticCamera;

// A ramp of radiance over 4 decades across the image, in constant patches of kPatchWidth columns.
constexpr int kLevels = 40;
constexpr int kPatchWidth = 8;
constexpr int kWidth = kLevels * kPatchWidth;
constexpr int kHeight = 24;
constexpr int kChannels = 3;
constexpr double kMaxRadiance = 400.0;  // Reads 0.8 of full scale in the shortest exposure.
constexpr double kDecades = 4.0;
const double kChannelScale[3] = {1.0, 0.8, 0.6};

double level_radiance(int level, int c) {
  return kMaxRadiance * std::pow(10.0, -kDecades * level / (kLevels - 1)) * kChannelScale[c];
}

std::vector<double> ramp_radiance() {
  std::vector<double> r(size_t(kWidth) * kHeight * kChannels);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      for (int c = 0; c < kChannels; ++c) {
        r[(size_t(y) * kWidth + x) * kChannels + c] = level_radiance(x / kPatchWidth, c);
      }
    }
  }
  return r;
}

struct Bracket {
  std::vector<RawFrame> frames;
  std::vector<Image> darks;
  std::vector<double> exposure_s;
  std::vector<double> gain;
  std::vector<BracketFrame> view() const {
    std::vector<BracketFrame> b;
    for (size_t k = 0; k < frames.size(); ++k) {
      b.push_back(BracketFrame{&frames[k], &darks[k], exposure_s[k], gain[k]});
    }
    return b;
  }
};

// Shoots the scene and 4 dark frames per step, as a capture would.
Bracket shoot_bracket(const SyntheticCamera& camera, const ResponseCurve& response,
                      const std::vector<double>& radiance, const std::vector<double>& exposure_s,
                      const std::vector<double>& gain, uint64_t seed) {
  std::mt19937_64 rng(seed);
  Bracket b;
  b.exposure_s = exposure_s;
  b.gain = gain;
  const std::vector<double> black(radiance.size(), 0.0);
  for (size_t k = 0; k < exposure_s.size(); ++k) {
    b.frames.push_back(
        camera.shoot(kWidth, kHeight, kChannels, radiance, exposure_s[k], gain[k], rng));
    std::vector<RawFrame> dark_frames;
    for (int r = 0; r < 4; ++r) {
      dark_frames.push_back(
          camera.shoot(kWidth, kHeight, kChannels, black, exposure_s[k], gain[k], rng));
    }
    std::vector<const RawFrame*> pointers;
    for (const RawFrame& d : dark_frames) pointers.push_back(&d);
    b.darks.push_back(mean_dark(pointers, response));
  }
  return b;
}

// Exposures x8 apart: 0.002 s to 1.024 s, so the longest sees the darkest patch at 4% of full scale
// and the shortest sees the brightest at 80%.
const std::vector<double> kExposures = {0.002, 0.016, 0.128, 1.024};
const std::vector<double> kUnitGain = {1, 1, 1, 1};

void expect_all_finite(const Image& image) {
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    ASSERT_TRUE(std::isfinite(image.pixels[i])) << "non-finite value at index " << i;
  }
}

TEST(HdrMerge, NoiseFreeRampIsRecoveredPerPixelWithinOnePercent) {
  for (double gamma : {1.0, 2.2}) {
    SyntheticCamera camera;
    camera.noise = false;
    camera.gamma = gamma;
    const ResponseCurve response = gamma == 1.0 ? ResponseCurve::linear(12, kChannels)
                                                : ResponseCurve::gamma(gamma, 12, kChannels);
    const std::vector<double> truth = ramp_radiance();
    const Bracket b = shoot_bracket(camera, response, truth, kExposures, kUnitGain, 1);
    const Image merged = merge_bracket(b.view(), response);
    ASSERT_EQ(merged.channels, kChannels + 1);
    expect_all_finite(merged);
    double worst = 0;
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        EXPECT_GE(merged.at(x, y, kChannels), 1.0f);
        for (int c = 0; c < kChannels; ++c) {
          const double t = truth[(size_t(y) * kWidth + x) * kChannels + c];
          worst = std::max(worst, std::abs(merged.at(x, y, c) / t - 1.0));
        }
      }
    }
    EXPECT_LT(worst, 0.01) << "gamma " << gamma;
    std::printf("noise-free merge, gamma %.1f: worst per-pixel relative error %.4f%%\n", gamma,
                100 * worst);
  }
}

TEST(HdrMerge, NoisyRampPatchMeansWithinOnePercentOverFourDecades) {
  const SyntheticCamera camera;  // Shot noise, 4 e- read noise, dark current, 1% black level.
  const ResponseCurve response = ResponseCurve::linear(12, kChannels);
  const std::vector<double> truth = ramp_radiance();
  const Bracket b = shoot_bracket(camera, response, truth, kExposures, kUnitGain, 2);
  const Image merged = merge_bracket(b.view(), response);
  expect_all_finite(merged);
  double worst = 0;
  for (int level = 0; level < kLevels; ++level) {
    for (int c = 0; c < kChannels; ++c) {
      double sum = 0;
      for (int y = 0; y < kHeight; ++y) {
        for (int x = level * kPatchWidth; x < (level + 1) * kPatchWidth; ++x) {
          sum += merged.at(x, y, c);
        }
      }
      const double mean = sum / (kHeight * kPatchWidth);
      const double rel = std::abs(mean / level_radiance(level, c) - 1.0);
      worst = std::max(worst, rel);
      EXPECT_LT(rel, 0.01) << "level " << level << " channel " << c << ": mean " << mean
                           << ", truth " << level_radiance(level, c);
    }
  }
  std::printf("noisy merge, 12-bit, 4 decades: worst patch-mean relative error %.4f%%\n",
              100 * worst);
}

TEST(HdrMerge, GainIsTreatedLikeExposure) {
  // The same bracket taken as shorter exposures at higher gain must merge to the same radiance.
  SyntheticCamera camera;
  camera.noise = false;
  const ResponseCurve response = ResponseCurve::linear(12, kChannels);
  const std::vector<double> truth = ramp_radiance();
  const Bracket b =
      shoot_bracket(camera, response, truth, {0.001, 0.008, 0.064, 0.512}, {2, 2, 2, 2}, 3);
  const Image merged = merge_bracket(b.view(), response);
  for (int x = 0; x < kWidth; x += 7) {
    const double t = truth[size_t(x) * kChannels];
    EXPECT_NEAR(merged.at(x, 5, 0) / t, 1.0, 0.01) << "x " << x;
  }
}

// A 1x1 single-channel frame with the given DN.
RawFrame pixel_frame(int dn) {
  RawFrame f;
  f.width = f.height = f.channels = 1;
  f.bit_depth = 12;
  f.pixels = {uint16_t(dn)};
  return f;
}

TEST(HdrMerge, SaturatedLongExposureGetsZeroWeight) {
  const ResponseCurve response = ResponseCurve::linear(12, 1);
  const Image dark(1, 1, 1, 0.0f);
  // Short exposure reads half scale; the long one (x16) clips. Were the clipped sample used at all,
  // it would pull the result far below 0.5 / 0.01 = 50.
  for (int long_dn : {4095, 4090, 4040}) {  // At max DN, and at/above 0.98 of full scale.
    const RawFrame short_frame = pixel_frame(2048);
    const RawFrame long_frame = pixel_frame(long_dn);
    const Image merged = merge_bracket(
        {{&short_frame, &dark, 0.01, 1.0}, {&long_frame, &dark, 0.16, 1.0}}, response);
    EXPECT_FLOAT_EQ(merged.at(0, 0, 0), float(2048.0 / 4095.0 / 0.01)) << "long DN " << long_dn;
    EXPECT_EQ(merged.at(0, 0, 1), 1.0f) << "long DN " << long_dn;
  }
}

// Each channel sees a different radiance, so that a channel mix-up shows: red at 10x full scale in
// the shortest exposure (every exposure saturated), green at half of full scale in the shortest
// (usable in that one only), blue at 0.05 (usable in the two shortest). Noise-free, so the only
// error is quantisation: half a DN in the frame and in the dark, i.e. at most 1 DN over the
// shortest exposure = 1 / 4095 / 0.002 s = 0.12.
TEST(HdrMerge, FullySaturatedChannelIsFlaggedAndALowerBoundOthersKeepTheirValues) {
  SyntheticCamera camera;
  camera.noise = false;
  const ResponseCurve response = ResponseCurve::linear(12, kChannels);
  const double truth[kChannels] = {5000.0, 250.0, 25.0};
  std::vector<double> radiance(size_t(kWidth) * kHeight * kChannels);
  for (size_t i = 0; i < radiance.size(); ++i) radiance[i] = truth[i % kChannels];
  const Bracket b = shoot_bracket(camera, response, radiance, kExposures, kUnitGain, 4);
  const Image merged = merge_bracket(b.view(), response);
  expect_all_finite(merged);
  const double one_dn = 1.0 / 4095 / kExposures[0];
  // The flag is the fewest usable samples of any channel: red has none.
  EXPECT_EQ(merged.at(3, 3, kChannels), 0.0f);
  // Red: the shortest exposure's value, (1 - dark) / 0.002 s, far below the truth.
  EXPECT_NEAR(merged.at(3, 3, 0), (1.0 - b.darks[0].at(3, 3, 0)) / kExposures[0], one_dn);
  EXPECT_LT(merged.at(3, 3, 0), 0.2 * truth[0]);
  // Green and blue: their true radiance, from the exposures that did not saturate.
  EXPECT_NEAR(merged.at(3, 3, 1), truth[1], one_dn);
  EXPECT_NEAR(merged.at(3, 3, 2), truth[2], one_dn);
}

TEST(HdrMerge, NeverOutputsNaNAndKeepsNegativeSignal) {
  const ResponseCurve response = ResponseCurve::linear(12, 1);
  // Frame darker than its dark frame (noise): the negative value is kept, not clipped to 0.
  const RawFrame zero = pixel_frame(0);
  const RawFrame low = pixel_frame(30);
  const Image dark(1, 1, 1, 40.0f / 4095.0f);
  const Image merged =
      merge_bracket({{&zero, &dark, 0.01, 1.0}, {&low, &dark, 0.1, 1.0}}, response);
  ASSERT_TRUE(std::isfinite(merged.at(0, 0, 0)));
  EXPECT_LT(merged.at(0, 0, 0), 0.0f);
  EXPECT_EQ(merged.at(0, 0, 1), 2.0f);
  // No dark frame and all-zero input: 0, not 0/0.
  const Image merged_no_dark = merge_bracket({{&zero, nullptr, 0.01, 1.0}}, response);
  EXPECT_EQ(merged_no_dark.at(0, 0, 0), 0.0f);
}

TEST(HdrMerge, MeanDarkAveragesLinearisedFrames) {
  const ResponseCurve response = ResponseCurve::gamma(2.0, 12, 1);
  const RawFrame a = pixel_frame(0);
  const RawFrame b = pixel_frame(4095);
  const Image mean = mean_dark({&a, &b}, response);
  EXPECT_FLOAT_EQ(mean.at(0, 0, 0), 0.5f);  // (0 + 1) / 2 in linear, not (0.5)^2 of the mean DN.
}

TEST(HdrMerge, RejectsMismatchedInput) {
  const ResponseCurve response = ResponseCurve::linear(12, 1);
  RawFrame a = pixel_frame(10);
  RawFrame wide = pixel_frame(10);
  wide.width = 2;
  wide.pixels.push_back(0);
  EXPECT_THROW(merge_bracket({{&a, nullptr, 0.01, 1.0}, {&wide, nullptr, 0.1, 1.0}}, response),
               InputError);
  EXPECT_THROW(merge_bracket({{&a, nullptr, 0.0, 1.0}}, response), InputError);
  EXPECT_THROW(merge_bracket({}, response), InputError);
  RawFrame ten_bit = pixel_frame(10);
  ten_bit.bit_depth = 10;
  EXPECT_THROW(merge_bracket({{&ten_bit, nullptr, 0.01, 1.0}}, response), InputError);
}

}  // namespace
}  // namespace ls::capture
