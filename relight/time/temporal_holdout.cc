// Model choice that cannot lose to the data (relight/time/temporal_fit.h, hold_out_steps): each
// pixel's model against the interpolation of its own per-step fits, at the steps left out.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "relight/time/temporal_fit.h"
#include "relight/time/temporal_fit_internal.h"

namespace ls::relight {
namespace {

using temporal_internal::add_departures;
using temporal_internal::CurveFit;
using temporal_internal::fit_constant;
using temporal_internal::fit_curve;
using temporal_internal::fit_process;
using temporal_internal::gather_series;
using temporal_internal::interpolate_params;
using temporal_internal::model_and_departure;
using temporal_internal::params_at;
using temporal_internal::Series;
using temporal_internal::shape_bounds;
using temporal_internal::ShapeBounds;
using temporal_internal::TemporalResult;
using temporal_internal::to_fitted_space;
using temporal_internal::to_physical;
using temporal_internal::write_curve;
using temporal_internal::write_process;

// `s` without its step k.
void without_step(const Series& s, int k, Series& out) {
  out.steps = 0;
  std::copy(std::begin(s.change_scale), std::end(s.change_scale), std::begin(out.change_scale));
  for (int i = 0; i < s.steps; ++i) {
    if (i == k) continue;
    out.t[out.steps] = s.t[i];
    std::copy_n(s.y[i], kTemporalParamCount, out.y[out.steps]);
    std::copy_n(s.w[i], kTemporalParamCount, out.w[out.steps]);
    ++out.steps;
  }
}

// Step k's chi^2 (curves' space, its own deviations) of a prediction q (curves' space).
double step_chi2(const Series& s, int k, const double* q) {
  double chi2 = 0;
  for (int p = 0; p < kTemporalParamCount; ++p) {
    const double r = (q[p] - s.y[k][p]) * s.w[k][p];
    chi2 += r * r;
  }
  return chi2;
}

// Interpolation's prediction of step k of `processes` from its neighbours there (the blend of
// their parameters that models_at_time gives a kSteps pixel), in the curves' space.
void interpolated_step(const Series& processes, int k, double* q) {
  const int before = k - 1, after = k + 1;
  const double w =
      (processes.t[k] - processes.t[before]) / (processes.t[after] - processes.t[before]);
  double a[kTemporalParamCount], b[kTemporalParamCount];
  for (int p = 0; p < kTemporalParamCount; ++p) {
    a[p] = to_physical(p, processes.y[before][p]);
    b[p] = to_physical(p, processes.y[after][p]);
  }
  interpolate_params(a, b, w, q);
  to_fitted_space(q);
}

// The chi^2 of predicting each interior step left out (what a render between steps sees; beyond
// the ends everything extrapolates) by the model in pixel channels m fitted again without it
// (*modelled), and by interpolating its neighbours (*interpolated). `processes` and `curves`: the
// pixel's series in each space.
struct HeldOutContext {
  const TemporalFitOptions& options;
  const ShapeBounds& bounds;
  double t_first, t_last;
};
void held_out_chi2(const float* m, const TemporalCurves* family, const Series& processes,
                   const Series& curves, const HeldOutContext& c, double* modelled,
                   double* interpolated) {
  const TemporalModel model = TemporalModel(int(m[kTModel]));
  // The pixel's own fit as the start of each refit (the processes' space: roughness as 1/m).
  TemporalResult start;
  start.rate = m[kTRate];
  start.onset = m[kTOnset];
  for (int p = 0; p < kTemporalParamCount; ++p) {
    const bool reciprocal = p == kParamRoughness;
    start.wet[p] = reciprocal ? 1 / std::max(double(m[kTWet + p]), 1e-6) : m[kTWet + p];
    start.dry[p] = reciprocal ? 1 / std::max(double(m[kTDry + p]), 1e-6) : m[kTDry + p];
  }
  thread_local Series reduced;
  float refit[kTemporalChannelCount];
  double q[kTemporalParamCount];
  *modelled = *interpolated = 0;
  for (int k = 1; k + 1 < curves.steps; ++k) {
    interpolated_step(processes, k, q);
    *interpolated += step_chi2(curves, k, q);
    std::copy_n(m, kTemporalChannelCount, refit);
    if (model == TemporalModel::kCurve) {
      if (family == nullptr) {
        *modelled = HUGE_VAL;
        return;
      }
      without_step(curves, k, reduced);
      const CurveFit f = fit_curve(reduced, *family, c.t_first, c.t_last - c.t_first);
      write_curve(f, int(m[kTCurve]), reduced.t[reduced.steps - 1], refit);
    } else {
      without_step(processes, k, reduced);
      const TemporalResult f =
          model == TemporalModel::kConstant
              ? fit_constant(reduced)
              : fit_process(model, reduced, c.bounds, c.options.max_iterations, &start);
      if (!f.ok) {
        *modelled = HUGE_VAL;
        return;
      }
      write_process(model, f, c.t_first, refit);
    }
    params_at(refit, curves.t[k], c.t_first, family, q);
    to_fitted_space(q);
    // With the refit's departures at the neighbours, as a render between them adds them.
    double departure[2][kTemporalParamCount], at_neighbour[kTemporalParamCount];
    for (int side = 0; side < 2; ++side) {
      model_and_departure(refit, family, c.t_first, curves, k - 1 + 2 * side, at_neighbour,
                          departure[side]);
    }
    add_departures(departure[0], departure[1],
                   (curves.t[k] - curves.t[k - 1]) / (curves.t[k + 1] - curves.t[k - 1]), q);
    *modelled += step_chi2(curves, k, q);
  }
}

// The parameters of a pixel's model, per the fit's BIC (temporal_models.cc, temporal_curves.cc).
double parameters_of(const float* m) {
  switch (TemporalModel(int(m[kTModel]))) {
    case TemporalModel::kConstant:
      return kTemporalParamCount;
    case TemporalModel::kDust:
      return 2 + temporal_internal::num_endpoint_params(TemporalModel::kDust);
    default:
      return temporal_internal::kCurveParameters;  // The exponential's and sigmoid's count too.
  }
}

// A process that explains the captured steps within their deviations (reduced chi^2 at most
// kUnexplainedResidual) keeps its pixel: it smooths their noise, and one pixel's few held-out steps
// would replace it by chance. A curve is always tested: learnt from these very steps, it can pass
// through them and miss what lies between (5 of the rise-and-fall lapse's 25 steps captured: held
// out 0.139 with only its unexplained pixels tested, 0.126 with every curve's; linear
// interpolation of the photos 0.125). Degenerate pixels render from their steps already.
bool held_out_candidate(const float* m) {
  return temporal_internal::renders_from_model(m) &&
         (TemporalModel(int(m[kTModel])) == TemporalModel::kCurve ||
          m[kTResidual] > temporal_internal::kUnexplainedResidual);
}

}  // namespace

void hold_out_steps(const std::vector<StepFit>& steps, const TemporalFitOptions& options,
                    TemporalMaps& band) {
  if (!options.hold_out_steps || steps.size() < 2) return;
  const ShapeBounds bounds = shape_bounds(band.step_times_s, options.max_rate_times_interval);
  const HeldOutContext context{options, bounds, band.first_time_s(), band.last_time_s()};
  const int width = band.maps.width, pixels = width * band.maps.height;
  tbb::parallel_for(0, pixels, [&](int i) {
    float* m = &band.maps.pixels[size_t(i) * kTemporalChannelCount];
    if (!held_out_candidate(m)) return;
    thread_local Series processes, curves;
    const int x = i % width, y = i / width;
    gather_series(steps, x, y, curves, /*curves=*/true);
    if (curves.steps < 2) return;
    gather_series(steps, x, y, processes);
    double modelled = 0, interpolated = 0;
    held_out_chi2(m, band.curves_at(x, y), processes, curves, context, &modelled, &interpolated);
    // The model's misfit at the captured steps beyond their noise (its chi^2 over its degrees of
    // freedom), per step, weighs with its prediction error between them: a model that smooths
    // the noise away keeps the pixel, one that misses what the steps show does not.
    const double n = double(curves.steps * kTemporalParamCount);
    const double dof = std::max(1.0, n - parameters_of(m));
    const double misfit = std::max(0.0, (m[kTResidual] - 1) * dof) / curves.steps;
    const double interior = std::max(curves.steps - 2, 1);
    // Interpolation must win by strong evidence (a chi^2 difference above kCurveEvidence, as a
    // curve over a process): one pixel's few held-out steps decide by chance otherwise.
    const double margin = modelled + misfit * interior - interpolated;
    if (!(margin > temporal_internal::kCurveEvidence)) return;
    const double samples = interior * double(kTemporalParamCount);
    m[kTModel] = float(TemporalModel::kSteps);
    m[kTRate] = 1;  // The time scale of the interpolation: rate edits scale it.
    m[kTOnset] = float(context.t_first);
    m[kTCurve] = m[kTCurveSeen] = 0;
    // Its first and last usable steps as its wet and dry ends (a transfer's target moves its end
    // state).
    const auto usable = [&](const StepFit& s) { return s.sigma.at(x, y, 0) > 0; };
    const StepFit& first = *std::find_if(steps.begin(), steps.end(), usable);
    const StepFit& last = *std::find_if(steps.rbegin(), steps.rend(), usable);
    for (int p = 0; p < kTemporalParamCount; ++p) {
      m[kTWet + p] = first.value.at(x, y, p);
      m[kTDry + p] = last.value.at(x, y, p);
    }
    m[kTConfidence] = float(1 / (1 + std::exp(-0.5 * std::min(margin, 1400.0))));
    m[kTResidual] = float(interpolated / samples);
  });
}

TemporalMaps every_pixel_from_its_steps(TemporalMaps maps, const std::vector<StepFit>& steps) {
  for (size_t i = 0; i < maps.maps.num_pixels(); ++i) {
    float* m = &maps.maps.pixels[i * kTemporalChannelCount];
    if (int(m[kTModel]) == int(TemporalModel::kNone)) continue;
    m[kTModel] = float(TemporalModel::kSteps);
    m[kTRate] = 1;
    m[kTFlags] = float(int(m[kTFlags]) & ~kTemporalDegenerate);
  }
  count_temporal_models(steps, maps);
  return maps;
}

}  // namespace ls::relight
