#pragma once
// Internal to the temporal fit (relight/temporal_fit*.cc): constants the per-step BRDF fits and the
// temporal curve models share. Not part of the public API. The solver core, samples and bounded
// parametrisations are relight/fit/pixel_solver.h, shared with the static fit.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "relight/fit/pixel_solver.h"
#include "relight/time/temporal_fit.h"

namespace ls::relight::temporal_internal {

using pixel::kMinRoughness;
using pixel::kPi;
inline constexpr double kMaxSigma = 0.5 * kPi;
// Standard deviation standing for "no information" (a parameter the step does not constrain, e.g.
// the roughness of a lobe with k_s = 0): weight 1e-12, i.e. none.
inline constexpr double kNoInformationSigma = 1e6;

// One pixel's per-step parameters over its usable steps (roughness as 1/m).
inline constexpr int kMaxSteps = 64;
struct Series {
  int steps = 0;  // Usable steps.
  double t[kMaxSteps];
  double y[kMaxSteps][kTemporalParamCount];
  double w[kMaxSteps][kTemporalParamCount];  // 1 / sigma, 0 = no information.
};

// Pixel (x, y)'s series from the per-step fits; returns the flags it found (kStepDropped,
// kTemporalNotConverged of a used step). lobe_peak: kParamKs holds the peak k_s / m^2 (curves).
int gather_series(const std::vector<StepFit>& steps, int x, int y, Series& series,
                  bool lobe_peak = false);

// Parameter p's endpoints given its shape s[i] at the series' steps: p_i = dry + (wet - dry) s_i by
// weighted least squares (a tiny ridge pulls wet toward dry where s is the same at every step);
// returns the parameter's chi^2.
inline double fit_endpoints(const Series& series, int p, const double* shape, double* wet,
                            double* dry) {
  Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  for (int i = 0; i < series.steps; ++i) {
    const double w2 = series.w[i][p] * series.w[i][p];
    const Eigen::Vector2d basis(1 - shape[i], shape[i]);
    a += w2 * basis * basis.transpose();
    b += w2 * basis * series.y[i][p];
  }
  const double ridge = 1e-9 * std::max(a.trace(), 1e-300);
  a(0, 0) += ridge;
  a(1, 1) += ridge;
  a(0, 1) -= ridge;
  a(1, 0) -= ridge;
  const Eigen::Vector2d x = a.ldlt().solve(b);
  *dry = std::isfinite(x(0)) ? x(0) : 0;
  *wet = std::isfinite(x(1)) ? x(1) : *dry;
  double chi2 = 0;
  for (int i = 0; i < series.steps; ++i) {
    const double r = (*dry + (*wet - *dry) * shape[i] - series.y[i][p]) * series.w[i][p];
    chi2 += r * r;
  }
  return chi2;
}

// The data-driven curves (temporal_curves.cc): learnt from a sample of changing pixels' series,
// and one pixel's best time warp and endpoints under them.
// start: the curves to refine (null: every curve starts as 1 - tau).
TemporalCurves learn_curves(const std::vector<Series>& sample, double t_first, double span,
                            int knots, const TemporalCurves* start = nullptr);
struct CurveFit {
  double chi2 = HUGE_VAL;
  double rate = 0, onset = 0;
  double wet[kTemporalParamCount] = {}, dry[kTemporalParamCount] = {};
};
CurveFit fit_curve(const Series& series, const TemporalCurves& curves, double t_first, double span);

}  // namespace ls::relight::temporal_internal
