// Temporal models fitted to per-step fits made by hand: a runaway process flagged and rendered
// from its steps, and curves learnt from a material that rises and falls.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <random>
#include <utility>
#include <vector>

#include "relight/time/temporal_render.h"
#include "tests/relight/time/temporal_scene.h"

namespace ls::relight {
namespace {

using namespace time_testing;  // NOLINT(google-build-using-namespace)

// A row of `width` pixels facing the camera.
NormalMap facing_the_camera(int width) {
  NormalMap normals;
  normals.normal = Image(width, 1, 3);
  normals.flags = Image(width, 1, 1);
  for (int x = 0; x < width; ++x) normals.normal.at(x, 0, 2) = 1;
  return normals;
}

// `count` hourly per-step fits of a row of `width` pixels, each parameter's deviation `sd`: grey
// albedo albedo(x, i) at step i, sigma 0.1, k_s 0.2, roughness 0.3.
std::vector<StepFit> hourly_steps(int width, int count, double sd,
                                  const std::function<double(int x, int i)>& albedo) {
  std::vector<StepFit> steps;
  for (int i = 0; i < count; ++i) {
    StepFit s;
    s.time_s = 3600.0 * i;
    s.value = Image(width, 1, kTemporalParamCount);
    s.sigma = Image(width, 1, kTemporalParamCount, float(sd));
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) s.value.at(x, 0, kParamAlbedoR + c) = float(albedo(x, i));
      s.value.at(x, 0, kParamSigma) = 0.1f;
      s.value.at(x, 0, kParamKs) = 0.2f;
      s.value.at(x, 0, kParamRoughness) = 0.3f;
    }
    steps.push_back(std::move(s));
  }
  return steps;
}

// A pixel whose albedo climbs in a straight line over the capture (the corroding metal's first
// phase) has no process that the data bound: exponential and sigmoid fit the line with a rate the
// span cannot show and endpoints far beyond the data (renders 270x too bright).
// Such a pixel is flagged and renders from its nearest per-step fit, in memory and after a round
// trip through the file; a pixel that follows a real exponential is not flagged.
TEST(TemporalFit, RunawayProcessIsFlaggedAndRendersFromTheNearestStep) {
  const int width = 2, count = 13;
  const NormalMap normals = facing_the_camera(width);
  const std::vector<StepFit> steps = hourly_steps(width, count, 0.003, [](int x, int i) {
    const double line = 0.05 + 0.07 * i / (count - 1);      // Pixel 0: a straight line.
    const double decay = 0.06 + 0.08 * std::exp(-i / 3.0);  // Pixel 1: an exponential.
    return x == 0 ? line : decay;
  });
  const TemporalMaps maps = fit_temporal_models(steps, normals, TemporalFitOptions{});
  const int line_flags = int(pixel_of(maps, 0, 0)[kTFlags]);
  const int decay_flags = int(pixel_of(maps, 1, 0)[kTFlags]);
  std::printf("line: model %s, rate %g /s, wet albedo %g, dry %g, flags %d; %s\n",
              to_string(maps.model(0, 0)), pixel_of(maps, 0, 0)[kTRate],
              pixel_of(maps, 0, 0)[kTWet], pixel_of(maps, 0, 0)[kTDry], line_flags,
              maps.summary.to_string().c_str());
  EXPECT_NE(line_flags & kTemporalDegenerate, 0);
  EXPECT_EQ(decay_flags & kTemporalDegenerate, 0);
  EXPECT_EQ(maps.summary.degenerate, 1);
  ASSERT_EQ(maps.step_values.channels, count * kTemporalParamCount);
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("runaway_" + std::to_string(::getpid()));
  write_temporal_maps(dir / "t.exr", maps);
  const TemporalMaps back = read_temporal_maps(dir / "t.exr");
  std::filesystem::remove_all(dir);
  EXPECT_EQ(back.step_values.pixels, maps.step_values.pixels);
  EXPECT_EQ(back.summary.degenerate, 1);
  for (const TemporalMaps* m : {&maps, &back}) {
    // 6.4 h: step 6 is nearest; 20 h (beyond the capture): the last step.
    for (const auto& [t, step] : {std::pair{6.4 * 3600, 6}, std::pair{20 * 3600.0, 12}}) {
      const TemporalState state = models_at_time(*m, t);
      EXPECT_FLOAT_EQ(state.maps.maps.at(0, 0, kMapAlbedoR),
                      steps[size_t(step)].value.at(0, 0, kParamAlbedoR))
          << t;
    }
  }
}

// A modelled pixel renders a captured step as its per-step fit where that fit departs from the
// model beyond its noise, and the model where the departure is within it (TemporalMaps::
// step_values): pixel 0 is constant but for one step 10 sigma off (a spill wiped off between two
// steps), pixel 1 for one step half a sigma off (noise). In memory and after a round trip through
// the file; a file from before (no modelled steps) renders the model alone.
TEST(TemporalFit, AModelRendersAStepThatDepartsBeyondItsNoiseAsItsFit) {
  const int width = 2, count = 13, odd = 6;
  const double sd = 0.003, base = 0.1;
  const double bump[width] = {10 * sd, 0.5 * sd};
  const std::vector<StepFit> steps = hourly_steps(
      width, count, sd, [&](int x, int i) { return base + (i == odd ? bump[x] : 0.0); });
  const NormalMap normals = facing_the_camera(width);
  TemporalMaps maps = fit_temporal_models(steps, normals, TemporalFitOptions{});
  for (int x = 0; x < width; ++x) {
    ASSERT_NE(maps.model(x, 0), TemporalModel::kSteps) << x;  // Modelled, not interpolated.
  }
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("departure_" + std::to_string(::getpid()));
  write_temporal_maps(dir / "t.exr", maps);
  const TemporalMaps back = read_temporal_maps(dir / "t.exr");
  std::filesystem::remove_all(dir);
  EXPECT_TRUE(back.modelled_steps);
  const auto albedo = [](const TemporalMaps& m, int x, double hours) {
    return double(models_at_time(m, hours * 3600).maps.maps.at(x, 0, kMapAlbedoR));
  };
  for (const TemporalMaps* m : {static_cast<const TemporalMaps*>(&maps), &back}) {
    const double model = pixel_of(*m, 0, 0)[kTDry];  // Constant: its value.
    // James-Stein keeps (1 - 1/z^2) of a departure z sigma: within 1/z of a sigma of the step.
    EXPECT_NEAR(albedo(*m, 0, odd), base + bump[0], sd / 9) << "model " << model;
    EXPECT_NEAR(albedo(*m, 0, odd + 1), model, 1e-6);  // Within its noise: the model.
    // Halfway to the next step: half the departure, on the model.
    EXPECT_NEAR(albedo(*m, 0, odd + 0.5), 0.5 * (albedo(*m, 0, odd) + model), 1e-5);
    EXPECT_NEAR(albedo(*m, 1, odd), pixel_of(*m, 1, 0)[kTDry], 1e-6);  // Noise: not rendered.
  }
  maps.modelled_steps = false;  // As a file from before the modelled steps reads.
  EXPECT_NEAR(albedo(maps, 0, odd), pixel_of(maps, 0, 0)[kTDry], 1e-6);
}

// A material that rises and falls (a corroding metal: red albedo 0.073 -> 0.118 -> 0.057,
// k_s 0.20 -> 0.01, roughness 0.065 -> 0.27), each pixel on its own clock (rate +-30%, onset
// +-1.5 h), captured every other hour of twelve with per-step noise. No process follows it: the
// curves learnt from the pixels do, and at the hours held out they are closer to the truth than
// linear interpolation between the captured neighbours; at the captured hours within the noise.
TEST(TemporalFit, CurvesFollowAMaterialThatRisesAndFalls) {
  const int width = 12, height = 8, hours = 13;
  const double sd = 0.003;
  const auto truth = [](int p, double tau) {
    tau = std::clamp(tau, 0.0, 1.0);
    const double bump = 4 * tau * (1 - tau) * std::exp(1 - 2 * tau);  // Up, then down.
    switch (p) {
      case kParamAlbedoR:
        return 0.073 + 0.06 * bump - 0.016 * tau;
      case kParamAlbedoG:
      case kParamAlbedoB:
        return 0.05 + 0.02 * bump;
      case kParamSigma:
        return 0.2;
      case kParamKs:
        return 0.20 - 0.19 * tau;
      default:
        return 1 / (1 / 0.065 + (1 / 0.27 - 1 / 0.065) * tau);  // Roughness, harmonic.
    }
  };
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, sd);
  std::uniform_real_distribution<double> rate_jitter(0.7, 1.3), onset_jitter(-1.5, 1.5);
  std::vector<double> rate(size_t(width) * height), onset(rate.size());
  for (size_t i = 0; i < rate.size(); ++i) {
    rate[i] = rate_jitter(rng) / (10 * 3600.0);
    onset[i] = onset_jitter(rng) * 3600;
  }
  NormalMap normals;
  normals.normal = Image(width, height, 3);
  normals.flags = Image(width, height, 1);
  for (size_t i = 0; i < rate.size(); ++i) normals.normal.pixels[3 * i + 2] = 1;
  std::vector<StepFit> all;
  for (int h = 0; h < hours; ++h) {
    StepFit s;
    s.time_s = 3600.0 * h;
    s.value = Image(width, height, kTemporalParamCount);
    s.sigma = Image(width, height, kTemporalParamCount, float(sd));
    for (size_t i = 0; i < rate.size(); ++i) {
      for (int p = 0; p < kTemporalParamCount; ++p) {
        const double v = truth(p, rate[i] * (s.time_s - onset[i]));
        s.value.pixels[i * kTemporalParamCount + size_t(p)] =
            float(p == kParamRoughness ? v : v + noise(rng));
      }
    }
    all.push_back(std::move(s));
  }
  std::vector<StepFit> captured;
  for (int h = 0; h < hours; h += 2) captured.push_back(all[size_t(h)]);
  const TemporalMaps maps = fit_temporal_models(captured, normals, TemporalFitOptions{});
  std::printf("%s\n", maps.summary.to_string().c_str());
  EXPECT_GT(maps.summary.per_model[int(TemporalModel::kCurve)], width * height / 2);
  // Error of the albedo and k_s against the truth, RMS over the pixels.
  const auto rms = [&](int h, const auto& value_of) {
    double sum = 0;
    int n = 0;
    for (size_t i = 0; i < rate.size(); ++i) {
      for (const int p : {int(kParamAlbedoR), int(kParamKs)}) {
        const double e = value_of(i, p) - truth(p, rate[i] * (3600.0 * h - onset[i]));
        sum += e * e, ++n;
      }
    }
    return std::sqrt(sum / n);
  };
  double held_model = 0, held_linear = 0, at_steps = 0;
  for (int h = 0; h < hours; ++h) {
    const TemporalState state = models_at_time(maps, 3600.0 * h);
    const auto model = [&](size_t i, int p) {
      const MapChannel c = p == kParamKs ? kMapKs : kMapAlbedoR;
      return double(state.maps.maps.pixels[i * kMapChannelCount + c]);
    };
    if (h % 2 == 0) {
      at_steps += rms(h, model) / 7;
      continue;
    }
    const auto linear = [&](size_t i, int p) {
      return 0.5 * (all[size_t(h - 1)].value.pixels[i * kTemporalParamCount + size_t(p)] +
                    all[size_t(h + 1)].value.pixels[i * kTemporalParamCount + size_t(p)]);
    };
    held_model += rms(h, model) / 6;
    held_linear += rms(h, linear) / 6;
  }
  std::printf(
      "held-out hours: curves %.4f, linear interpolation %.4f; captured hours %.4f "
      "(noise %.4f)\n",
      held_model, held_linear, at_steps, sd);
  EXPECT_LT(held_model, held_linear);
  EXPECT_LT(at_steps, 1.1 * sd);
  // A time edit on the curves: twice as fast, the edited material at t is the original at 2 t.
  TemporalMaps fast = maps;
  const std::vector<int> edited = apply_temporal_edits(
      parse_temporal_edits(R"({"time": [{"select": {"model": "curve"}, "rate_scale": 2}]})",
                           "fast.json", ".", width, height),
      fast);
  EXPECT_EQ(edited[0], maps.summary.per_model[int(TemporalModel::kCurve)]);
  const TemporalState at_3h = models_at_time(fast, 3 * 3600.0);
  const TemporalState at_6h = models_at_time(maps, 6 * 3600.0);
  for (size_t i = 0; i < rate.size(); ++i) {
    if (maps.maps.pixels[i * kTemporalChannelCount + kTModel] != float(TemporalModel::kCurve)) {
      continue;  // Not edited.
    }
    EXPECT_NEAR(at_3h.maps.maps.pixels[i * kMapChannelCount + kMapAlbedoR],
                at_6h.maps.maps.pixels[i * kMapChannelCount + kMapAlbedoR], 1e-5);
  }
}

}  // namespace
}  // namespace ls::relight
