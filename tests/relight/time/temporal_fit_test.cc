// Temporal BRDF fits (relight/time/temporal_fit.h) and rendering at any time
// (relight/time/temporal_render.h) against the simulator's time-varying scene (sim/time_varying.h).
#include "relight/time/temporal_fit.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>

#include "lightstage/errors.h"
#include "relight/time/temporal_render.h"
#include "sim/sim_stage.h"
#include "tests/relight/time/time_fixtures.h"

namespace ls::relight {
namespace {

using time_testing::field_at;
using time_testing::truth_of;

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

struct World {
  Stage stage;
  sim::Scene scene;
  std::vector<sim::SurfaceHit> hits;
};

World make_world(int leds = 50, int width = 32, int height = 24) {
  World w;
  w.stage = stage_with_directions(fibonacci_dome_directions(leds, -11.5));
  w.stage.camera.width = width;
  w.stage.camera.height = height;
  w.scene = sim::time_varying_scene();
  // The wet surface dries to its own base colour (the scene file gives only "wet").
  for (sim::SceneMaterial& m : w.scene.materials) {
    if (m.process && m.process->kind == sim::ProcessKind::kWetDrying) m.process->dry = m.base;
  }
  w.hits = sim::trace_camera(w.scene, w.stage.camera);
  return w;
}

std::vector<capture::ReflectanceField> capture_steps(const World& w,
                                                     const std::vector<double>& times,
                                                     uint64_t seed = 1) {
  std::vector<capture::ReflectanceField> steps;
  for (size_t i = 0; i < times.size(); ++i) {
    steps.push_back(field_at(w.stage, w.scene, times[i], NoiseModel{}, seed + i));
  }
  return steps;
}

const std::vector<double> kTimes = {0, 40, 80, 120, 180, 240, 300, 390, 480, 600};

struct Fitted {
  World world;
  TemporalMaps maps;
};
const Fitted& fitted_scene() {
  static const Fitted f = [] {
    Fitted out{make_world(40), {}};
    out.maps = fit_temporal(capture_steps(out.world, kTimes), TemporalFitOptions{});
    return out;
  }();
  return f;
}

const float* pixel_of(const TemporalMaps& maps, int x, int y) {
  return maps.maps.pixels.data() + (size_t(y) * maps.maps.width + x) * kTemporalChannelCount;
}

enum Region { kPaint, kDust, kWet, kStatic };
// Which process a hit shows (kStatic: none, or outside its material's region).
Region region_of(const World& w, const sim::SurfaceHit& h) {
  const sim::ProcessTruth t = truth_of(w.scene, h);
  if (!t.varying) return kStatic;
  if (t.kind == sim::ProcessKind::kPaintDrying) return kPaint;
  if (t.kind == sim::ProcessKind::kDustSettling) return kDust;
  return kWet;
}

struct RegionStats {
  int pixels = 0, right_model = 0, varying_model = 0;
  std::vector<double> rate_error, onset_error, wet_error, dry_error, ks_wet_error;
};

std::map<Region, RegionStats> region_stats(const World& w, const TemporalMaps& maps) {
  std::map<Region, RegionStats> out;
  for (const sim::SurfaceHit& h : w.hits) {
    if (!h.hit) continue;
    const Region r = region_of(w, h);
    RegionStats& st = out[r];
    ++st.pixels;
    const TemporalModel m = maps.model(h.pixel_x, h.pixel_y);
    const TemporalModel expected = r == kPaint  ? TemporalModel::kExponential
                                   : r == kDust ? TemporalModel::kDust
                                   : r == kWet  ? TemporalModel::kSigmoid
                                                : TemporalModel::kConstant;
    st.right_model += m == expected;
    st.varying_model += m != TemporalModel::kConstant && m != TemporalModel::kNone;
    // A curve's endpoints are its extremes in its own space (temporal_fit.h), not the process's.
    if (r == kStatic || m == TemporalModel::kConstant || m == TemporalModel::kNone ||
        m == TemporalModel::kCurve) {
      continue;
    }
    const sim::ProcessTruth t = truth_of(w.scene, h);
    const float* p = pixel_of(maps, h.pixel_x, h.pixel_y);
    st.rate_error.push_back(std::abs(p[kTRate] / t.rate_per_s - 1));
    st.onset_error.push_back(std::abs(p[kTOnset] - t.onset_s));
    st.wet_error.push_back((Eigen::Vector3d(p[kTWet], p[kTWet + 1], p[kTWet + 2]) - t.wet.albedo)
                               .cwiseAbs()
                               .maxCoeff());
    st.dry_error.push_back((Eigen::Vector3d(p[kTDry], p[kTDry + 1], p[kTDry + 2]) - t.dry.albedo)
                               .cwiseAbs()
                               .maxCoeff());
    st.ks_wet_error.push_back(std::abs(double(p[kTWet + int(kParamKs)]) - t.wet.ks.x()));
  }
  return out;
}

void print_stats(const std::map<Region, RegionStats>& stats) {
  const char* names[] = {"paint", "dust", "wet", "static"};
  for (const auto& [r, st] : stats) {
    std::printf(
        "%-6s pixels %3d right model %3d varying %3d | median |rate/true - 1| %.4f, |onset err| "
        "%.3f s, wet albedo %.4f, dry albedo %.4f, wet ks %.4f\n",
        names[r], st.pixels, st.right_model, st.varying_model, median(st.rate_error),
        median(st.onset_error), median(st.wet_error), median(st.dry_error),
        median(st.ks_wet_error));
  }
}

// At realistic noise (NoiseModel defaults: 2% at diffuse white) with 10 steps over 600 s. The scene
// and its noise are seeded, so every value below is reproducible: the bounds are regression guards,
// the measured value (in the comments) with a margin of about 25% of it (a few pixels for counts).
TEST(TemporalFit, RecoversEachProcessAndKeepsStaticPixelsConstant) {
  const Fitted& f = fitted_scene();
  std::printf("%s\n", f.maps.summary.to_string().c_str());
  const auto stats = region_stats(f.world, f.maps);
  print_stats(stats);
  const RegionStats& paint = stats.at(kPaint);
  const RegionStats& dust = stats.at(kDust);
  const RegionStats& wet = stats.at(kWet);
  const RegionStats& still = stats.at(kStatic);
  // Nearly every varying pixel is given a varying model (measured with 40 LEDs, 32x24, normals
  // from the driest step: paint 36/37, dust 36/37, wet 114/114).
  EXPECT_GE(paint.varying_model, paint.pixels - 3);
  EXPECT_GE(dust.varying_model, dust.pixels - 3);
  EXPECT_GE(wet.varying_model, wet.pixels - 3);
  // The right process for most (measured: paint 24/37 exponential, the rest sigmoid/dust-shaped
  // near the silhouette; dust 35/37; wet 114/114 sigmoid).
  EXPECT_GE(paint.right_model, 0.55 * paint.pixels);
  EXPECT_GE(dust.right_model, dust.pixels - 4);
  EXPECT_GE(wet.right_model, wet.pixels - 4);
  // Rates (measured medians: paint 0.052, dust 0.0086, wet 0.018 relative).
  EXPECT_LT(median(paint.rate_error), 0.07);
  EXPECT_LT(median(dust.rate_error), 0.012);
  EXPECT_LT(median(wet.rate_error), 0.025);
  // Onsets (measured: paint 1.2 s: it starts at 0 = the first step; dust 0.96 s; wet 0.6 s).
  EXPECT_LT(median(paint.onset_error), 1.6);
  EXPECT_LT(median(dust.onset_error), 1.2);
  EXPECT_LT(median(wet.onset_error), 0.8);
  // Albedo endpoints, worst channel (measured: paint wet 0.010 dry 0.022; dust 0.004/0.003; wet
  // 0.002/0.003). The paint's wet k_s is NOT recovered with 40 LEDs (error 0.34 of 0.5: its m =
  // 0.08 lobe is too sharp for the LED spacing) and not asserted; the dust's is, on half its pixels
  // (below).
  EXPECT_LT(median(paint.wet_error), 0.014);
  EXPECT_LT(median(paint.dry_error), 0.028);
  EXPECT_LT(median(dust.wet_error), 0.0065);
  EXPECT_LT(median(dust.dry_error), 0.0052);
  EXPECT_LT(median(wet.wet_error), 0.0028);
  EXPECT_LT(median(wet.dry_error), 0.004);
  // Static pixels (matte sphere, backdrop, the plane outside the patch) get the constant model
  // (measured: 565 of 580).
  EXPECT_GE(still.right_model, 0.95 * still.pixels);
  // The dust's wet k_s splits in two: within 0.03 where the steps' fits see the clean gloss (m =
  // 0.15), the whole 0.45 off where no LED catches that lobe at the first steps (measured: 17 of
  // 34 pixels within 0.03). A median would sit on the edge between the two groups.
  const auto caught = std::count_if(dust.ks_wet_error.begin(), dust.ks_wet_error.end(),
                                    [](double e) { return e < 0.05; });
  EXPECT_GE(caught, 14) << "of " << dust.ks_wet_error.size();
}

// Which field the fixed normals come from: every step pooled, the first (wettest) or the last
// (driest). Mean angle to the true normal over pixels all three estimate.
TEST(TemporalFit, DriestStepNormalsAreTheMostAccurate) {
  const World w = make_world(40);
  const std::vector<capture::ReflectanceField> steps = capture_steps(w, kTimes);
  double sum[4] = {0, 0, 0, 0};
  int count = 0;
  const auto normals = [&](NormalSource source, bool refine) {
    TemporalFitOptions options;
    options.normal_source = source;
    options.refine_normals = refine;
    return estimate_temporal_normals(steps, options);
  };
  const NormalMap maps[4] = {
      normals(NormalSource::kPooled, false), normals(NormalSource::kFirst, false),
      normals(NormalSource::kLast, false), normals(NormalSource::kLast, true)};
  for (const sim::SurfaceHit& h : w.hits) {
    if (!h.hit) continue;
    bool ok = true;
    for (const NormalMap& m : maps) ok = ok && m.flags.at(h.pixel_x, h.pixel_y, 0) == 0;
    if (!ok) continue;
    ++count;
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d n(maps[k].normal.at(h.pixel_x, h.pixel_y, 0),
                              maps[k].normal.at(h.pixel_x, h.pixel_y, 1),
                              maps[k].normal.at(h.pixel_x, h.pixel_y, 2));
      sum[k] += std::acos(std::clamp(n.normalized().dot(h.normal), -1.0, 1.0)) * 180 / M_PI;
    }
  }
  std::printf(
      "mean normal error over %d pixels: pooled %.3f deg, first %.3f deg, last %.3f deg, last "
      "refined by the fit %.3f deg\n",
      count, sum[0] / count, sum[1] / count, sum[2] / count, sum[3] / count);
  // Measured: pooled 0.727, first 0.707, last 0.584 degrees. The wet steps carry the strongest
  // and sharpest lobes (paint k_s 0.5 at m 0.08, the clean gloss under the dust), which bias
  // photometric stereo even with the robust estimator; pooling averages that bias in and also
  // mixes albedos that differ between steps. Hence NormalSource::kLast by default.
  EXPECT_GT(count, 500);
  EXPECT_LT(sum[2], 0.95 * sum[0]);
  EXPECT_LT(sum[2], 0.95 * sum[1]);
  EXPECT_LT(sum[2] / count, 0.73);  // Regression guard: measured 0.584 deg.
}

// Rendering at an uncaptured time (150 s, between steps) and beyond the last step (1200 s)
// against the simulator's ideal one-light images at those times, lit from directions no LED
// covers exactly. Pixels in a cast shadow of the true scene are left out (the models have no
// visibility).
double render_error(const Fitted& f, double time_s, int* extrapolated) {
  const std::vector<sim::SurfaceHit> truth_hits = sim::at_time(f.world.scene, f.world.hits, time_s);
  double err2 = 0, ref2 = 0;
  for (const Eigen::Vector3d& dir :
       {Eigen::Vector3d(0.25, 0.3, 0.92), Eigen::Vector3d(-0.4, 0.1, 0.91)}) {
    const Eigen::Vector3d l = dir.normalized();
    const Image truth = sim::render_one_light(f.world.scene, truth_hits, l);
    const Image model =
        render_temporal(f.maps, time_s, LightingForModels::directional(l, Eigen::Vector3d(1, 1, 1)),
                        {}, extrapolated);
    for (const sim::SurfaceHit& h : f.world.hits) {
      if (!h.hit || f.maps.model(h.pixel_x, h.pixel_y) == TemporalModel::kNone) continue;
      if (!sim::visible(f.world.scene, h.position + 1e-3 * h.normal, l)) continue;
      for (int c = 0; c < 3; ++c) {
        const double t = truth.at(h.pixel_x, h.pixel_y, c), m = model.at(h.pixel_x, h.pixel_y, c);
        EXPECT_TRUE(std::isfinite(m));
        err2 += (m - t) * (m - t);
        ref2 += t * t;
      }
    }
  }
  return std::sqrt(err2 / ref2);
}

TEST(TemporalRender, UncapturedTimeMatchesTruthAndExtrapolationIsFlagged) {
  const Fitted& f = fitted_scene();
  int extrapolated = -1;
  const double between = render_error(f, 150, &extrapolated);
  std::printf("relative RMS error at t = 150 s (between steps): %.4f\n", between);
  // Measured 0.076 (0.076 at the captured step 120 s too: the error is the BRDF fit's, not the
  // temporal model's; sharp lobes between 40 LEDs are the most of it).
  EXPECT_LT(between, 0.095);
  EXPECT_EQ(extrapolated, 0);
  const double captured = render_error(f, 120, &extrapolated);
  std::printf("relative RMS error at t = 120 s (a captured step): %.4f\n", captured);
  const double beyond = render_error(f, 1200, &extrapolated);
  std::printf("relative RMS error at t = 1200 s (2x the last step): %.4f, %d pixels flagged\n",
              beyond, extrapolated);
  // Every varying pixel is flagged, none of the constant ones; the error stays bounded (measured
  // 0.076) because the fitted processes have settled by the last step.
  EXPECT_EQ(extrapolated, f.maps.summary.fitted - f.maps.summary.per_model[1]);
  EXPECT_LT(beyond, 0.095);
  const TemporalState state = models_at_time(f.maps, 1200);
  int flagged = 0;
  for (size_t i = 0; i < state.maps.maps.num_pixels(); ++i) {
    flagged += (int(state.maps.maps.pixels[i * kMapChannelCount + kMapFlags]) & kExtrapolated) != 0;
  }
  EXPECT_EQ(flagged, extrapolated);
}

// Three steps: fewer than a process needs (4 parameters per series + 1): only the constant model,
// every fitted pixel flagged kTooFewSteps, all values finite.
TEST(TemporalFit, TooFewStepsGivesFlaggedConstant) {
  const World w = make_world(40, 16, 12);
  const TemporalMaps maps = fit_temporal(capture_steps(w, {0, 120, 300}), TemporalFitOptions{});
  EXPECT_GT(maps.summary.fitted, 100);
  EXPECT_EQ(maps.summary.per_model[1], maps.summary.fitted);
  EXPECT_EQ(maps.summary.too_few_steps, maps.summary.fitted);
  for (const float v : maps.maps.pixels) EXPECT_TRUE(std::isfinite(v));
}

// The solvers' status reaches the flags. Per step: with the BRDF fits stopped after one
// iteration, every pixel whose chosen step model has sigma or a lobe (the Lambert start is the
// closed-form optimum, so a Lambert fit converges at once) is flagged kTemporalNotConverged, and
// the temporal maps carry the bit of every used step; at the default limit almost none is flagged.
// Temporal models: stopped after one iteration, every pixel whose chosen model is a process (not
// the closed-form constant) is flagged.
TEST(TemporalFit, IterationLimitIsFlaggedNotConverged) {
  const World w = make_world(40, 16, 12);
  const std::vector<capture::ReflectanceField> fields =
      capture_steps(w, {0, 60, 120, 240, 360, 600});
  TemporalFitOptions step_limit;
  // The LM solver's limit (the default step fits are closed-form: no iterations to run out of).
  step_limit.brdf.solver = FitSolver::kEveryCandidateByLm;
  step_limit.brdf.max_iterations = 1;
  const NormalMap normals = estimate_temporal_normals(fields, step_limit);
  std::vector<StepFit> steps;
  int lobe_or_sigma = 0, used = 0, flagged_at_default = 0;
  for (const capture::ReflectanceField& field : fields) {
    steps.push_back(fit_step(field, normals, step_limit));
    const StepFit& s = steps.back();
    const StepFit converged = fit_step(field, normals, TemporalFitOptions{});
    for (int y = 0; y < 12; ++y) {
      for (int x = 0; x < 16; ++x) {
        used += converged.sigma.at(x, y, 0) > 0;
        flagged_at_default += converged.flags.at(x, y, 0) != 0;
        if (!(s.sigma.at(x, y, 0) > 0)) continue;
        if (s.value.at(x, y, kParamSigma) > 0 || s.value.at(x, y, kParamKs) > 0) {
          ++lobe_or_sigma;
          EXPECT_EQ(int(s.flags.at(x, y, 0)), kTemporalNotConverged) << x << ", " << y;
        }
      }
    }
  }
  EXPECT_GT(lobe_or_sigma, 20);
  // Measured: 1 of 1150 used step pixels still stops on the default 50.
  EXPECT_LE(flagged_at_default, used / 100) << "of " << used;
  std::printf("%d of %d used step pixels not converged at the default limit\n", flagged_at_default,
              used);
  const TemporalMaps a = fit_temporal_models(steps, normals, step_limit);
  int carried = 0;
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 16; ++x) {
      bool any_step = false;
      for (const StepFit& s : steps) {
        any_step = any_step || (s.sigma.at(x, y, 0) > 0 && s.flags.at(x, y, 0) != 0);
      }
      if (!any_step) continue;
      ++carried;
      EXPECT_TRUE(int(pixel_of(a, x, y)[kTFlags]) & kTemporalNotConverged) << x << ", " << y;
    }
  }
  EXPECT_GT(carried, 10);
  EXPECT_GE(a.summary.not_converged, carried);

  TemporalFitOptions model_limit;
  model_limit.max_iterations = 1;
  model_limit.fit_curves = false;  // Curves are fitted in closed form: no solver status.
  const TemporalMaps b = fit_temporal(fields, model_limit);
  std::printf("%s\n", b.summary.to_string().c_str());
  int processes = 0;
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 16; ++x) {
      const TemporalModel m = b.model(x, y);
      if (m == TemporalModel::kNone || m == TemporalModel::kConstant) continue;
      ++processes;
      EXPECT_TRUE(int(pixel_of(b, x, y)[kTFlags]) & kTemporalNotConverged) << x << ", " << y;
    }
  }
  EXPECT_GT(processes, 10);
}

// A step with most LEDs dead (5 left: too few for a BRDF fit anywhere): that step is dropped at
// every pixel and flagged, and the processes are still recovered from the others.
TEST(TemporalFit, StepWithDeadLedsIsDroppedAndFlagged) {
  const World w = make_world(40, 24, 18);
  std::vector<capture::ReflectanceField> steps;
  const std::vector<double> times = {0, 40, 80, 120, 180, 240, 330, 450, 600};
  std::vector<int> dead;
  for (int l = 5; l < 40; ++l) dead.push_back(l);
  for (size_t i = 0; i < times.size(); ++i) {
    steps.push_back(field_at(w.stage, w.scene, times[i], NoiseModel{}, 7 + i,
                             times[i] == 120 ? dead : std::vector<int>{}));
  }
  const TemporalMaps maps = fit_temporal(steps, TemporalFitOptions{});
  std::printf("%s\n", maps.summary.to_string().c_str());
  EXPECT_EQ(maps.summary.step_dropped, maps.summary.fitted);
  const auto stats = region_stats(w, maps);
  print_stats(stats);
  // Measured: dust rate 0.014, wet rate 0.024 relative.
  EXPECT_LT(median(stats.at(kDust).rate_error), 0.018);  // Regression guards (+25%).
  EXPECT_LT(median(stats.at(kWet).rate_error), 0.03);
  for (const float v : maps.maps.pixels) EXPECT_TRUE(std::isfinite(v));
}

// Paint drying 30x faster than the 60 s sampling (lambda = 0.5/s): between two samples it goes
// from wet to dry, so the curve is a step; the rate is held at its bound (4 / 60 s) and flagged,
// and the endpoints are still right.
TEST(TemporalFit, ProcessFasterThanSamplingIsBoundedAndFlagged) {
  World w = make_world(40, 16, 12);
  for (sim::SceneMaterial& m : w.scene.materials) {
    if (m.process && m.process->kind == sim::ProcessKind::kPaintDrying) {
      m.process->rate_per_s = 0.5;
      m.process->onset_s = 150;
    }
  }
  const TemporalMaps maps =
      fit_temporal(capture_steps(w, {0, 60, 120, 180, 240, 300, 360}), TemporalFitOptions{});
  int paint = 0, flagged = 0;
  for (const sim::SurfaceHit& h : w.hits) {
    if (region_of(w, h) != kPaint || maps.model(h.pixel_x, h.pixel_y) == TemporalModel::kNone) {
      continue;
    }
    ++paint;
    const float* p = pixel_of(maps, h.pixel_x, h.pixel_y);
    if (int(p[kTFlags]) & kFasterThanSampling) ++flagged;
    EXPECT_LE(p[kTRate], 4.0 / 60 * 1.001);
    if (p[kTModel] != float(TemporalModel::kConstant)) {
      EXPECT_GE(p[kTOnset], 60.0);  // The step lies between the samples at 120 and 180.
      EXPECT_LE(p[kTOnset], 240.0);
    }
  }
  std::printf("paint pixels %d, flagged faster than sampling %d\n", paint, flagged);
  EXPECT_GT(paint, 5);
  EXPECT_GE(flagged, 0.6 * paint);  // Measured: 7 of 9.
}

TEST(TemporalEdit, RateScaleAndTransfer) {
  const Fitted& f = fitted_scene();
  const int width = f.maps.maps.width, height = f.maps.maps.height;
  // Rate scale on the dust process: the edited curve at t is the original at 2 t (first step 0).
  TemporalMaps edited = f.maps;
  const TemporalEdits speed =
      parse_temporal_edits(R"({"time": [{"select": {"model": "dust"}, "rate_scale": 2.0}]})",
                           "speed.json", ".", width, height);
  const std::vector<int> counts = apply_temporal_edits(speed, edited);
  ASSERT_EQ(counts.size(), 1u);
  // Degenerate pixels render from their per-step fits: no process to edit.
  const auto degenerate = [&](int x, int y) {
    return (int(pixel_of(f.maps, x, y)[kTFlags]) & kTemporalDegenerate) != 0;
  };
  int dust = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x)
      dust += f.maps.model(x, y) == TemporalModel::kDust && !degenerate(x, y);
  }
  EXPECT_EQ(counts[0], dust);
  EXPECT_GT(dust, f.maps.summary.per_model[int(TemporalModel::kDust)] * 9 / 10);
  const TemporalState fast = models_at_time(edited, 100);
  const TemporalState slow = models_at_time(f.maps, 200);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      if (f.maps.model(x, y) != TemporalModel::kDust || degenerate(x, y)) continue;
      EXPECT_NEAR(fast.maps.maps.at(x, y, kMapAlbedoR), slow.maps.maps.at(x, y, kMapAlbedoR), 1e-4);
    }
  }
  // Transfer the sigmoid (wet sand drying) onto the static matte sphere: it takes the sigmoid,
  // its rate and onset, and keeps its own dry albedo.
  std::vector<uint8_t> matte(size_t(width) * height, 0);
  for (const sim::SurfaceHit& h : f.world.hits) {
    if (h.hit && f.world.scene.materials[h.material_index].name == "matte-white") {
      matte[size_t(h.pixel_y) * width + h.pixel_x] = 1;
    }
  }
  TemporalEdits transfer;
  transfer.source = "transfer";
  TemporalEdit edit;
  edit.select.mask = matte;
  edit.transfer_from = TemporalSelection{TemporalModel::kSigmoid, {}, {}};
  transfer.edits.push_back(edit);
  TemporalMaps moved = f.maps;
  apply_temporal_edits(transfer, moved);
  int changed = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      if (!matte[size_t(y) * width + x] || f.maps.model(x, y) == TemporalModel::kNone) continue;
      ++changed;
      EXPECT_EQ(moved.model(x, y), TemporalModel::kSigmoid);
      EXPECT_EQ(moved.at(x, y, kTDry), f.maps.at(x, y, kTDry));
      // Wet sand is 0.14/0.5 = 0.28 of its dry red: so is the sphere's wet red now.
      EXPECT_NEAR(moved.at(x, y, kTWet) / moved.at(x, y, kTDry), 0.28, 0.05);
    }
  }
  EXPECT_GT(changed, 10);
  // A source with no varying process is refused, naming the edit.
  TemporalEdits bad = transfer;
  bad.edits[0].transfer_from = TemporalSelection{TemporalModel::kConstant, {}, {}};
  EXPECT_THROW(apply_temporal_edits(bad, moved), InputError);
  EXPECT_THROW(parse_temporal_edits(R"({"time": [{"select": {}, "rate_scale": -1}]})", "bad.json",
                                    ".", width, height),
               InputError);
}

// A pixel whose albedo climbs in a straight line over the capture (the corroding metal's first
// phase) has no process that the data bound: exponential and sigmoid fit the line with a rate the
// span cannot show and endpoints far beyond the data (renders 270x too bright).
// Such a pixel is flagged and renders from its nearest per-step fit, in memory and after a round
// trip through the file; a pixel that follows a real exponential is not flagged.
TEST(TemporalFit, RunawayProcessIsFlaggedAndRendersFromTheNearestStep) {
  const int width = 2, count = 13;
  NormalMap normals;
  normals.normal = Image(width, 1, 3);
  normals.flags = Image(width, 1, 1);
  for (int x = 0; x < width; ++x) normals.normal.at(x, 0, 2) = 1;
  std::vector<StepFit> steps;
  for (int i = 0; i < count; ++i) {
    StepFit s;
    s.time_s = 3600.0 * i;
    s.value = Image(width, 1, kTemporalParamCount);
    s.sigma = Image(width, 1, kTemporalParamCount, 0.003f);
    const double line = 0.05 + 0.07 * i / (count - 1);      // Pixel 0: a straight line.
    const double decay = 0.06 + 0.08 * std::exp(-i / 3.0);  // Pixel 1: an exponential.
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c)
        s.value.at(x, 0, kParamAlbedoR + c) = float(x == 0 ? line : decay);
      s.value.at(x, 0, kParamSigma) = 0.1f;
      s.value.at(x, 0, kParamKs) = 0.2f;
      s.value.at(x, 0, kParamRoughness) = 0.3f;
    }
    steps.push_back(std::move(s));
  }
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
    EXPECT_NEAR(at_3h.maps.maps.pixels[i * kMapChannelCount + kMapAlbedoR],
                at_6h.maps.maps.pixels[i * kMapChannelCount + kMapAlbedoR], 1e-5);
  }
}

TEST(TemporalMapsFile, RoundTrips) {
  const World w = make_world(40, 16, 12);
  Fitted f{w, fit_temporal(capture_steps(w, {0, 60, 120, 180, 300, 600}), TemporalFitOptions{})};
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("temporal_maps_" + std::to_string(::getpid()));
  write_temporal_maps(dir / "t.exr", f.maps);
  const TemporalMaps back = read_temporal_maps(dir / "t.exr");
  EXPECT_EQ(back.maps.pixels, f.maps.maps.pixels);
  EXPECT_EQ(back.step_times_s, f.maps.step_times_s);
  EXPECT_TRUE(std::filesystem::exists(dir / "t.rate.png"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace ls::relight
