#pragma once
// Internal to the temporal fit (relight/temporal_fit*.cc): constants the per-step BRDF fits and the
// temporal curve models share. Not part of the public API. The solver core, samples and bounded
// parametrisations are relight/fit/pixel_solver.h, shared with the static fit.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "physics/brdf.h"
#include "relight/fit/pixel_solver.h"
#include "relight/time/temporal_fit.h"

namespace ls::relight::temporal_internal {

using pixel::kMinRoughness;
using pixel::kPi;
inline constexpr double kMaxSigma = 0.5 * kPi;
// Standard deviation standing for "no information" (a parameter the step does not constrain, e.g.
// the roughness of a lobe with k_s = 0): weight 1e-12, i.e. none.
inline constexpr double kNoInformationSigma = 1e6;

// A BRDF parameter clamped to its bounds.
inline double clamp_param(int p, double v) {
  if (p == kParamSigma) return std::clamp(v, 0.0, kMaxSigma);
  if (p == kParamRoughness) return std::clamp(v, kMinRoughness, 1.0);
  return std::max(v, 0.0);
}

// The BRDF's parameters to and from the space the curves follow (temporal_fit.h): albedo
// A(sigma), sigma, the peak k_s / m^2, 1/m; from it clamped to their bounds.
inline void to_fitted_space(double* q) {
  const double a = physics::brdf::oren_nayar_a(q[kParamSigma]), m = q[kParamRoughness];
  for (int c = 0; c < 3; ++c) q[c] *= a;
  q[kParamKs] /= m * m;
  q[kParamRoughness] = 1 / m;
}
inline void from_fitted_space(double* y) {
  y[kParamSigma] = clamp_param(kParamSigma, y[kParamSigma]);
  const double m =
      clamp_param(kParamRoughness, y[kParamRoughness] > 0 ? 1 / y[kParamRoughness] : 1.0);
  const double a = physics::brdf::oren_nayar_a(y[kParamSigma]);
  for (int c = 0; c < 3; ++c) y[c] = clamp_param(c, y[c] / a);
  y[kParamKs] = clamp_param(kParamKs, y[kParamKs] * m * m);
  y[kParamRoughness] = m;
}

// A pixel's BRDF parameters q at time t from its temporal maps channels m (clamped to their
// bounds). A process follows the BRDF's parameters (the roughness harmonic: 1/m follows it); a
// curve its own space (temporal_fit.h), its endpoints stored in it, and holds what its steps saw
// (kTCurveSeen; before the first step, first_time_s).
void params_at(const float* m, double t, double first_time_s, const TemporalCurves* curves,
               double* q);

// One pixel's per-step parameters over its usable steps (gather_series).
inline constexpr int kMaxSteps = 64;
struct Series {
  int steps = 0;  // Usable steps.
  double t[kMaxSteps];
  double y[kMaxSteps][kTemporalParamCount];
  double w[kMaxSteps][kTemporalParamCount];  // 1 / sigma, 0 = no information.
  // gather_series(curves): per parameter the scale of a plausible change, twice the larger
  // of the range its informative steps span and 3 of their smallest deviations; a curve's wet -
  // dry carries the prior N(0, scale^2) so that where its steps barely see the curve move (the
  // roughness where k_s is 0 at most steps) its endpoints stay near the data rather than run to
  // wherever the curve's extreme is. 0: none (the processes).
  double change_scale[kTemporalParamCount] = {};
};

// Pixel (x, y)'s series from the per-step fits; returns the flags it found (kStepDropped,
// kTemporalNotConverged of a used step). In the processes' space (the BRDF's parameters, the
// roughness as 1/m), or with `curves` in the curves' (to_fitted_space).
int gather_series(const std::vector<StepFit>& steps, int x, int y, Series& series,
                  bool curves = false);
// What a series' informative steps (weight > 0) show of parameter p: the range of its values,
// their largest and smallest deviations and the times they span. informed() false: none.
struct ParamRange {
  double lo = HUGE_VAL, hi = -HUGE_VAL, largest_sigma = 0, smallest_sigma = HUGE_VAL;
  double t0 = HUGE_VAL, t1 = -HUGE_VAL;
  bool informed() const { return hi >= lo; }
  // How far beyond the range a model may go before it has run away from the data.
  double margin() const { return (hi - lo) + 3 * largest_sigma; }
};
inline ParamRange range_of(const Series& series, int p) {
  ParamRange r;
  for (int i = 0; i < series.steps; ++i) {
    if (!(series.w[i][p] > 0)) continue;
    r.lo = std::min(r.lo, series.y[i][p]);
    r.hi = std::max(r.hi, series.y[i][p]);
    r.largest_sigma = std::max(r.largest_sigma, 1 / series.w[i][p]);
    r.smallest_sigma = std::min(r.smallest_sigma, 1 / series.w[i][p]);
    r.t0 = std::min(r.t0, series.t[i]);
    r.t1 = std::max(r.t1, series.t[i]);
  }
  return r;
}

// Endpoints a dust fit has besides rate and onset (others: wet and dry of every parameter).
inline constexpr int num_endpoint_params(TemporalModel model) {
  return model == TemporalModel::kDust ? 9 : 2 * kTemporalParamCount;
}

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
  if (!(a.trace() > 0)) {  // No step informs p: its values stand (a fit's placeholder), constant.
    *wet = *dry = series.steps > 0 ? series.y[0][p] : 0.0;
    return 0;
  }
  const double scale = series.change_scale[p];
  const double prior = scale > 0 ? 1 / (scale * scale) : 0.0;
  const double ridge = prior + 1e-9 * std::max(a.trace(), 1e-300);
  a(0, 0) += ridge;
  a(1, 1) += ridge;
  a(0, 1) -= ridge;
  a(1, 0) -= ridge;
  // The 2x2 solve in closed form (the ridge keeps it positive definite).
  const double det = a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0);
  const Eigen::Vector2d x = det > 0 ? Eigen::Vector2d((a(1, 1) * b(0) - a(0, 1) * b(1)) / det,
                                                      (a(0, 0) * b(1) - a(1, 0) * b(0)) / det)
                                    : Eigen::Vector2d(a.ldlt().solve(b));
  *dry = std::isfinite(x(0)) ? x(0) : 0;
  *wet = std::isfinite(x(1)) ? x(1) : *dry;
  double chi2 = prior * (*wet - *dry) * (*wet - *dry);
  for (int i = 0; i < series.steps; ++i) {
    const double r = (*dry + (*wet - *dry) * shape[i] - series.y[i][p]) * series.w[i][p];
    chi2 += r * r;
  }
  return chi2;
}

// The processes (temporal_processes.cc). Each parameter follows p(t) = dry + (wet - dry) s(t), s =
// 1 at the wet end, 0 at the dry end; the roughness series is fitted as 1/m (the processes' space).
// s(t) of a model at time t (0 for constant).
double shape_weight(TemporalModel model, double rate, double onset, double t);
// Bounds of the nonlinear parameters.
struct ShapeBounds {
  double log_rate_lo, log_rate_hi;
  double onset_lo, onset_hi;
};
// Rates from 5% of the change over 100 spans to max_rate_times_interval / the smallest interval;
// onsets within the steps' span. Zero for fewer than two steps.
ShapeBounds shape_bounds(const std::vector<double>& step_times, double max_rate_times_interval);
struct TemporalResult {
  bool ok = false;
  pixel::SolverStatus status = pixel::SolverStatus::kConverged;  // Of LM (none: closed form).
  double chi2 = std::numeric_limits<double>::infinity();
  int k = 0;
  double rate = 0, onset = 0;
  double wet[kTemporalParamCount] = {}, dry[kTemporalParamCount] = {};  // The processes' space.
};
TemporalResult fit_constant(const Series& s);
// A process (exponential, sigmoid, dust; constant for any other model) by a grid start over
// (rate, onset) refined by Levenberg-Marquardt, or refined from `start` (a fit of the same model).
TemporalResult fit_process(TemporalModel model, const Series& s, const ShapeBounds& bounds,
                           int iterations, const TemporalResult* start = nullptr);
// A value of the processes' space back in the BRDF's (the roughness from 1/m).
double to_physical(int p, double v);
// BRDF parameters a linear blend (1 - w) a + w b of two steps', as a render between two per-step
// fits sees them (TemporalModel::kSteps): in the BRDF's own space, where the lobe's energy (k_s)
// and width (m) move apart (the peak k_s / m^2 and 1/m, blended, make a sharp lobe of a broad
// one's energy); the roughness of a step without a lobe (k_s 0), which it does not measure, is the
// other's.
void interpolate_params(const double* a, const double* b, double w, double* q);
// A process's fit into a pixel's channels (temporal_fit.h, TemporalChannel): model, rate, onset
// (t_first for the constant), wet and dry in the BRDF's space, clamped to its bounds.
void write_process(TemporalModel model, const TemporalResult& f, double t_first, float* m);

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
// A curve's fit into a pixel's channels (model, family, rate, onset, wet, dry, and the curve
// position its steps saw up to time seen_until).
void write_curve(const CurveFit& f, int family, double seen_until, float* m);

// A per-step fit's departure r from a model at its step (curves' space), kept in proportion to
// how far it stands out of the step's deviation 1/w: James-Stein's positive part, r (1 - 1/z^2)
// for z = r w beyond 1, else 0. Noise the model smooths is dropped, a departure of many deviations
// kept whole (TemporalMaps::step_values).
inline double significant_departure(double r, double w) {
  const double z2 = (r * w) * (r * w);
  return z2 > 1 ? r * (1 - 1 / z2) : 0.0;
}
// Steps i and j's departures (d_i, d_j) interpolated to the fraction `w` of the way from i to j,
// added to the model's parameters q there (all in the curves' space).
inline void add_departures(const double* d_i, const double* d_j, double w, double* q) {
  for (int p = 0; p < kTemporalParamCount; ++p) q[p] += (1 - w) * d_i[p] + w * d_j[p];
}

// Whether a pixel with temporal map channels m renders from its model (a fitted pixel neither
// kSteps nor degenerate: those render from their per-step fits).
inline bool renders_from_model(const float* m) {
  const TemporalModel model = TemporalModel(int(m[kTModel]));
  return model != TemporalModel::kNone && model != TemporalModel::kSteps &&
         (int(m[kTFlags]) & kTemporalDegenerate) == 0;
}
// The model in temporal map channels m (curve family `family`) at series step j, in the curves'
// space, and that step's significant departure from it.
void model_and_departure(const float* m, const TemporalCurves* family, double first_time_s,
                         const Series& series, int j, double* model, double* departure);
// Modelled pixel (x, y)'s steps in band.step_values (TemporalMaps::step_values): its model at
// each step plus, with `steps`, the step's fit's significant departure from it (none at a step
// unusable there); without, the model alone (an edited pixel follows its edited model).
void write_modelled_steps(const std::vector<StepFit>* steps, int x, int y, TemporalMaps& band);

// A series no model explains leaves a reduced chi^2 above this (the per-step parameters carry
// their own uncertainties and a floor for model error, so a right model leaves about 1; the
// simulator's paint, an exponential, leaves up to 3 on a few pixels).
inline constexpr double kUnexplainedResidual = 4;
// Strong evidence for one model over another: a BIC (or chi^2) difference above 6 (Kass and
// Raftery 1995).
inline constexpr double kCurveEvidence = 6;
// A curve's parameters: rate, onset, wet and dry of each parameter (the exponential's count).
inline constexpr int kCurveParameters = 2 + 2 * kTemporalParamCount;
// A curve family is learnt from at least this many series.
inline constexpr size_t kMinFamilySeries = 10;

// Curve families (TemporalCurves, one per way of changing) and a series' best one by chi^2.
struct FamilyFit {
  int family = 0;
  CurveFit fit;
};
FamilyFit best_family(const Series& series, const std::vector<TemporalCurves>& families,
                      double t_first, double span);
std::vector<TemporalCurves> learn_families(const std::vector<Series>& sample, int knots,
                                           double t_first, double span);

}  // namespace ls::relight::temporal_internal
