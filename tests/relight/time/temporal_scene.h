#pragma once
// The time-varying simulated scene of the temporal-fit tests, captured at a list of times and
// fitted once, and the fit's errors per process region against the simulator's truth.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <vector>

#include "relight/time/temporal_fit.h"
#include "sim/sim_stage.h"
#include "tests/relight/time/time_fixtures.h"

namespace ls::relight::time_testing {

inline double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

struct World {
  Stage stage;
  sim::Scene scene;
  std::vector<sim::SurfaceHit> hits;
};

inline World make_world(int leds = 50, int width = 32, int height = 24) {
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

inline std::vector<capture::ReflectanceField> capture_steps(const World& w,
                                                            const std::vector<double>& times,
                                                            uint64_t seed = 1) {
  std::vector<capture::ReflectanceField> steps;
  for (size_t i = 0; i < times.size(); ++i) {
    steps.push_back(field_at(w.stage, w.scene, times[i], NoiseModel{}, seed + i));
  }
  return steps;
}

inline const std::vector<double> kTimes = {0, 40, 80, 120, 180, 240, 300, 390, 480, 600};

struct Fitted {
  World world;
  TemporalMaps maps;
};
inline const Fitted& fitted_scene() {
  static const Fitted f = [] {
    Fitted out{make_world(40), {}};
    out.maps = fit_temporal(capture_steps(out.world, kTimes), TemporalFitOptions{});
    return out;
  }();
  return f;
}

inline const float* pixel_of(const TemporalMaps& maps, int x, int y) {
  return maps.maps.pixels.data() + (size_t(y) * maps.maps.width + x) * kTemporalChannelCount;
}

enum Region { kPaint, kDust, kWet, kStatic };
// Which process a hit shows (kStatic: none, or outside its material's region).
inline Region region_of(const World& w, const sim::SurfaceHit& h) {
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

inline std::map<Region, RegionStats> region_stats(const World& w, const TemporalMaps& maps) {
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

inline void print_stats(const std::map<Region, RegionStats>& stats) {
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

}  // namespace ls::relight::time_testing
