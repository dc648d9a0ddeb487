// The checks a frame passes on arrival (frame_checks.h), on synthetic frames whose light, noise and
// faults are known: a consistent bracket passes (linear or gamma-encoded once linearised, with
// saturated highlights), and each fault is caught in the frame that has it.
#include "lightstage/controller/frame_checks.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace ls {
namespace {

constexpr int kW = 128, kH = 96, kBits = 12;
constexpr double kBlack = 0.01;  // Offset, fraction of full scale.

// Normalised exposure per second of a scene with shading and a bright disc.
double Scene(int x, int y) {
  const double shade = 0.5 + 0.4 * std::sin(0.05 * x) * std::cos(0.07 * y);
  const double disc = std::hypot(x - 80.0, y - 40.0) < 12 ? 3.0 : 0.0;
  return 4.0 * (shade + disc);
}

// A frame of Scene exposed for `seconds`, read noise 0.05% of full scale, encoded with `gamma`.
RawFrame Expose(double seconds, unsigned seed, double gamma = 1.0,
                double (*scene)(int, int) = Scene) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.0005);
  RawFrame f{kW, kH, 1, kBits, std::vector<uint16_t>(size_t(kW) * kH)};
  const double max_dn = f.max_value();
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      const double light = scene ? scene(x, y) * seconds : 0.0;
      // Shot noise: relative 1% at full scale.
      const double shot = std::sqrt(std::max(light, 0.0)) * 0.01 * noise(rng) / 0.0005;
      const double v = std::clamp(kBlack + light + shot + noise(rng), 0.0, 1.0);
      f.pixels[size_t(y) * kW + x] = uint16_t(std::lround(std::pow(v, 1.0 / gamma) * max_dn));
    }
  }
  return f;
}

std::vector<float> MeanDark(double gamma = 1.0) {
  const RawFrame dark = Expose(0.0, 99, gamma, nullptr);
  return std::vector<float>(dark.pixels.begin(), dark.pixels.end());
}

class Bracket : public ::testing::Test {
 protected:
  void Shoot(double gamma = 1.0) {
    dark_ = MeanDark(gamma);
    frames_.clear();
    for (int e = 0; e < 3; ++e) frames_.push_back(Expose(exposures_[e], 10 + e, gamma));
  }
  std::vector<std::string> Check(const DnToLinear& to_linear = {}) {
    std::vector<BracketFrame> bracket;
    for (int e = 0; e < 3; ++e) bracket.push_back({&frames_[e], exposures_[e], 1.0, &dark_, e});
    return bracket_problems(bracket, to_linear);
  }
  const double exposures_[3] = {0.01, 0.04, 0.16};
  std::vector<float> dark_;
  std::vector<RawFrame> frames_;
};

TEST_F(Bracket, AConsistentBracketPassesWithItsHighlightsSaturated) {
  Shoot();
  // The longest exposure clips the disc (4 * 4 * 0.16 > 1): clipped values are left out.
  EXPECT_EQ(frames_[2].pixels[size_t(40) * kW + 80], frames_[2].max_value());
  for (const std::string& p : Check()) EXPECT_EQ(p, "");
}

TEST_F(Bracket, AGammaEncodedBracketPassesOnlyOnceLinearised) {
  Shoot(2.2);
  const DnToLinear inverse_gamma = [](int dn, int) { return std::pow(dn / 4095.0, 2.2); };
  for (const std::string& p : Check(inverse_gamma)) EXPECT_EQ(p, "");
  // Taken as linear, the exposures do not scale the codes: every frame disagrees.
  for (const std::string& p : Check()) EXPECT_NE(p, "");
}

TEST_F(Bracket, ATornFrameIsCaughtAndItsRowsNamed) {
  Shoot();
  // The transfer of the middle exposure broke off at row 72: the rest is zeros.
  std::fill(frames_[1].pixels.begin() + 72 * kW, frames_[1].pixels.end(), uint16_t(0));
  const auto problems = Check();
  EXPECT_EQ(problems[0], "");
  EXPECT_EQ(problems[2], "");
  EXPECT_NE(problems[1].find("rows 72-95"), std::string::npos) << problems[1];
}

TEST_F(Bracket, AStaleFrameIsCaught) {
  Shoot();
  frames_[2] = frames_[1];  // The previous trigger's buffer delivered again.
  const auto problems = Check();
  EXPECT_EQ(problems[0], "");
  EXPECT_EQ(problems[1], "");
  EXPECT_NE(problems[2], "");
}

TEST_F(Bracket, AFrameUnderOtherLightIsCaught) {
  Shoot();
  frames_[0] = Expose(0.01, 5, 1.0, [](int x, int y) { return 2.0 + 0.03 * x - 0.02 * y; });
  const auto problems = Check();
  EXPECT_NE(problems[0], "");
  EXPECT_EQ(problems[1], "");
  EXPECT_EQ(problems[2], "");
}

TEST_F(Bracket, AnExposureTheCameraDidNotApplyIsCaught) {
  Shoot();
  frames_[1] = Expose(0.02, 11);  // Reported as 0.04 s.
  const auto problems = Check();
  EXPECT_NE(problems[1], "");
  EXPECT_EQ(problems[0], "");
}

TEST_F(Bracket, TwoFramesThatDisagreeAreBothShotAgain) {
  Shoot();
  frames_.pop_back();
  frames_[1] = frames_[0];
  std::vector<BracketFrame> pair = {{&frames_[0], exposures_[0], 1.0, &dark_, 0},
                                    {&frames_[1], exposures_[1], 1.0, &dark_, 1}};
  for (const std::string& p : bracket_problems(pair, {})) EXPECT_NE(p, "");
}

TEST_F(Bracket, WithoutADarkReferenceNothingIsJudged) {
  Shoot();
  frames_[2] = frames_[1];
  std::vector<BracketFrame> bracket = {{&frames_[1], exposures_[1], 1.0, &dark_, 1},
                                       {&frames_[2], exposures_[2], 1.0, nullptr, 2}};
  for (const std::string& p : bracket_problems(bracket, {})) EXPECT_EQ(p, "");
}

TEST(DarkFrame, NoiseAndHotPixelsAreDarkAndAStuckLedIsNot) {
  RawFrame dark = Expose(0.0, 1, 1.0, nullptr);
  EXPECT_EQ(dark_frame_problem(dark, 0.01), "");
  // 0.5% of the pixels hot (at 10% of full scale, ten times the black level), as a long exposure on
  // a warm sensor shows: more than the 0.1% a percentile of the pixels would let pass.
  for (size_t p = 0; p < dark.pixels.size(); p += 200) dark.pixels[p] = dark.max_value() / 10;
  EXPECT_EQ(dark_frame_problem(dark, 0.01), "");
  const std::string lit = dark_frame_problem(Expose(0.005, 1), 0.01);
  EXPECT_NE(lit.find("stuck"), std::string::npos) << lit;
}

}  // namespace
}  // namespace ls
