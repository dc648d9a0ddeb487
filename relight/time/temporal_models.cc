// The BIC choice among the processes (constant / exponential / sigmoid / dust,
// temporal_processes.cc) per pixel (relight/time/temporal_fit.h, step 3).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>
#include <vector>

#include "lightstage/errors.h"
#include "relight/fit/pixel_solver.h"
#include "relight/time/temporal_fit.h"
#include "relight/time/temporal_fit_internal.h"

namespace ls::relight {
namespace {

using pixel::SolverStatus;
using temporal_internal::fit_constant;
using temporal_internal::fit_process;
using temporal_internal::kMaxSteps;
using temporal_internal::Series;
using temporal_internal::shape_bounds;
using temporal_internal::shape_weight;
using temporal_internal::ShapeBounds;
using temporal_internal::TemporalResult;
using temporal_internal::write_process;

struct PixelContext {
  const TemporalFitOptions& options;
  const ShapeBounds& bounds;
  const std::vector<double>& step_times;
  double t_first, span;
};

// Whether a process fit ran away from the series (kTemporalDegenerate): an onset at the last step
// (the change happens after the data), a rate the span cannot show (the curve barely moves while
// its endpoints are extrapolated), or an endpoint of a moving parameter beyond the range of the
// series' values by more than that range and 3 sigma.
bool endpoints_run_away(const Series& series, const double* wet, const double* dry) {
  for (int p = 0; p < kTemporalParamCount; ++p) {
    const temporal_internal::ParamRange r = temporal_internal::range_of(series, p);
    if (!r.informed()) continue;  // No information on this parameter.
    for (const double end : {wet[p], dry[p]}) {
      if (end < r.lo - r.margin() || end > r.hi + r.margin()) return true;
    }
  }
  return false;
}

bool ran_away(const Series& series, const TemporalResult& f, const PixelContext& c) {
  if (c.span <= 0) return false;
  if (f.onset >= c.t_first + c.span * (1 - 1e-6)) return true;
  if (f.rate * c.span < kMinRateTimesSpan) return true;
  return endpoints_run_away(series, f.wet, f.dry);
}

// Fits the temporal models to one pixel's series, chooses by BIC and writes the chosen model into
// m; flags: what the series gathering found. Counts fitted and flagged pixels in local; returns the
// BIC of the model written (HUGE_VAL when none).
double fit_pixel_models(const Series& series, int flags, const PixelContext& c, float* m,
                        TemporalSummary& local) {
  std::array<TemporalResult, kTemporalModelCount> fits;
  fits[1] = fit_constant(series);
  // A model needs more usable steps than its parameters per series (4: wet, dry, rate, onset).
  const bool enough = series.steps >= 5;
  const bool wants_process =
      c.options.fit_exponential || c.options.fit_sigmoid || c.options.fit_dust;
  if (!enough && wants_process) flags |= kTooFewSteps;
  if (enough && c.options.fit_exponential) {
    fits[2] = fit_process(TemporalModel::kExponential, series, c.bounds, c.options.max_iterations);
  }
  if (enough && c.options.fit_sigmoid) {
    fits[3] = fit_process(TemporalModel::kSigmoid, series, c.bounds, c.options.max_iterations);
  }
  if (enough && c.options.fit_dust) {
    fits[4] = fit_process(TemporalModel::kDust, series, c.bounds, c.options.max_iterations);
  }
  const double n = double(series.steps * kTemporalParamCount);
  int best = 0;
  std::array<double, kTemporalModelCount> bic;
  bic.fill(std::numeric_limits<double>::infinity());
  // Order of simplicity for ties: constant (6), dust (11), exponential, sigmoid (14).
  for (const int k : {1, 4, 2, 3}) {
    if (!fits[k].ok) continue;
    bic[k] = fits[k].chi2 + fits[k].k * std::log(n);
    if (best == 0 || bic[k] < bic[best]) best = k;
  }
  if (best == 0) {
    m[kTFlags] = float(flags | kTemporalFitFailed);
    ++local.flagged;
    ++local.no_usable_step;
    return HUGE_VAL;
  }
  const TemporalResult& f = fits[best];
  if (f.status != SolverStatus::kConverged) flags |= kTemporalNotConverged;
  double weight_sum = 0;
  for (int k = 1; k < kTemporalModelCount; ++k) {
    if (std::isfinite(bic[k])) weight_sum += std::exp(-0.5 * (bic[k] - bic[best]));
  }
  const TemporalModel model = TemporalModel(best);
  if (model != TemporalModel::kConstant) {
    // Faster than sampling: 90% or more of the change falls between two consecutive steps (or the
    // rate sits at its bound): the curve there is a step whose rate and onset the data only bound.
    double max_jump = 0;
    for (size_t i = 1; i < c.step_times.size(); ++i) {
      max_jump =
          std::max(max_jump, std::abs(shape_weight(model, f.rate, f.onset, c.step_times[i]) -
                                      shape_weight(model, f.rate, f.onset, c.step_times[i - 1])));
    }
    if (max_jump >= 0.9 || std::log(f.rate) >= c.bounds.log_rate_hi - 0.05) {
      flags |= kFasterThanSampling;
    }
    if (f.onset <= c.t_first + 1e-6 * std::max(c.span, 1.0) && model != TemporalModel::kSigmoid) {
      flags |= kOnsetAtCaptureStart;
    }
    if (ran_away(series, f, c)) flags |= kTemporalDegenerate;
  }
  write_process(model, f, c.t_first, m);
  m[kTConfidence] = float(1 / weight_sum);
  const double dof = n - f.k;
  m[kTResidual] = float(dof > 0 ? f.chi2 / dof : f.chi2);
  m[kTStepsUsed] = float(series.steps);
  m[kTFlags] = float(flags);
  ++local.fitted;  // Models and flags are counted from the maps once the curves are offered.
  return bic[best];
}

// The per-step fits of the given pixels (TemporalMaps::step_values); a step unusable at a pixel
// takes its nearest usable step's values.
Image step_values_of(const std::vector<StepFit>& steps, const std::vector<int>& pixels, int width,
                     int height) {
  const int count = int(steps.size());
  Image out(width, height, count * kTemporalParamCount);
  for (int i = 0; i < count; ++i) {
    for (int p = 0; p < kTemporalParamCount; ++p) {
      out.channel_names.push_back("step." + std::to_string(i) + "." + temporal_param_name(p));
    }
  }
  for (const int pixel : pixels) {
    const int x = pixel % width, y = pixel / width;
    for (int i = 0; i < count; ++i) {
      int nearest = -1;
      for (int j = 0; j < count; ++j) {
        const bool usable = steps[size_t(j)].sigma.at(x, y, 0) > 0;
        if (usable && (nearest < 0 ||
                       std::abs(steps[size_t(j)].time_s - steps[size_t(i)].time_s) <
                           std::abs(steps[size_t(nearest)].time_s - steps[size_t(i)].time_s))) {
          nearest = j;
        }
      }
      for (int p = 0; nearest >= 0 && p < kTemporalParamCount; ++p) {
        out.at(x, y, i * kTemporalParamCount + p) = steps[size_t(nearest)].value.at(x, y, p);
      }
    }
  }
  return out;
}

}  // namespace

double temporal_value(TemporalModel model, double rate, double onset, double wet, double dry,
                      double t, const TemporalCurves* curves, int p) {
  const double s = model == TemporalModel::kCurve
                       ? (curves && !curves->empty() ? curves->at(p, rate * (t - onset)) : 0.0)
                       : shape_weight(model, rate, onset, t);
  return dry + (wet - dry) * s;
}

namespace {

void check_steps(const std::vector<StepFit>& steps, const TemporalFitOptions& options) {
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError("temporal fit options: " + error);
  }
  if (steps.empty()) throw InputError("temporal fit: expected at least one time step, got none");
  if (steps.size() > size_t(kMaxSteps)) {
    throw InputError("temporal fit: expected at most " + std::to_string(kMaxSteps) +
                     " time steps, got " + std::to_string(steps.size()));
  }
}

}  // namespace

TemporalMaps fit_temporal_processes(const std::vector<StepFit>& steps, const NormalMap& normals,
                                    const TemporalFitOptions& options,
                                    std::vector<double>& best_bic) {
  check_steps(steps, options);
  const int width = normals.normal.width, height = normals.normal.height;
  TemporalMaps out;
  out.maps = Image(width, height, kTemporalChannelCount);
  out.maps.channel_names = temporal_channel_names();
  for (const StepFit& s : steps) out.step_times_s.push_back(s.time_s);
  out.noise = options.brdf.normals.noise;
  out.noise_source = options.brdf.noise_source;
  const double t_first = out.step_times_s.front(), t_last = out.step_times_s.back();
  const double span = t_last - t_first;
  const ShapeBounds bounds = shape_bounds(out.step_times_s, options.max_rate_times_interval);
  const PixelContext context{options, bounds, out.step_times_s, t_first, span};
  TemporalSummary& summary = out.summary;
  summary.pixels = width * height;
  std::mutex mutex;
  best_bic.assign(size_t(width) * height, HUGE_VAL);
  std::atomic<long> rows_done{0};
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    TemporalSummary local;
    Series series;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        float* m = &out.maps.at(x, y, 0);
        int flags = 0;
        if (int(normals.flags.at(x, y, 0)) != 0) {
          m[kTFlags] = kTemporalNoNormal;
          ++local.flagged;
          ++local.no_normal;
          continue;
        }
        for (int c = 0; c < 3; ++c) m[kTNormalX + c] = normals.normal.at(x, y, c);
        flags |= temporal_internal::gather_series(steps, x, y, series);
        if (series.steps == 0) {
          m[kTFlags] = float(flags | kTemporalFitFailed);
          ++local.flagged;
          ++local.no_usable_step;
          continue;
        }
        best_bic[size_t(y) * width + x] = fit_pixel_models(series, flags, context, m, local);
      }
      const long done = ++rows_done;
      report(options.progress, "fit over time", done, height);
    }
    const std::lock_guard lock(mutex);
    summary.fitted += local.fitted;
    summary.flagged += local.flagged;
    summary.no_normal += local.no_normal;
    summary.no_usable_step += local.no_usable_step;
  });
  return out;
}

void count_temporal_models(const std::vector<StepFit>& steps, TemporalMaps& band) {
  const int width = band.maps.width, height = band.maps.height;
  TemporalSummary& summary = band.summary;
  std::fill(std::begin(summary.per_model), std::end(summary.per_model), 0);
  summary.faster_than_sampling = summary.too_few_steps = summary.step_dropped = 0;
  summary.not_converged = summary.degenerate = 0;
  // The pixels that render from their per-step fits, and those that render from their models.
  std::vector<int> from_steps, modelled;
  for (int i = 0; i < width * height; ++i) {
    const float* m = &band.maps.pixels[size_t(i) * kTemporalChannelCount];
    const int model = int(m[kTModel]), flags = int(m[kTFlags]);
    if (model == 0) continue;
    ++summary.per_model[model];
    summary.faster_than_sampling += (flags & kFasterThanSampling) != 0;
    summary.too_few_steps += (flags & kTooFewSteps) != 0;
    summary.step_dropped += (flags & kStepDropped) != 0;
    summary.not_converged += (flags & kTemporalNotConverged) != 0;
    summary.degenerate += (flags & kTemporalDegenerate) != 0;
    (temporal_internal::renders_from_model(m) ? modelled : from_steps).push_back(i);
  }
  summary.curve_families = int(band.curves.size());
  band.step_values = from_steps.empty() && modelled.empty()
                         ? Image{}
                         : step_values_of(steps, from_steps, width, height);
  band.modelled_steps = true;
  tbb::parallel_for(size_t(0), modelled.size(), [&](size_t k) {
    temporal_internal::write_modelled_steps(&steps, modelled[k] % width, modelled[k] / width, band);
  });
}

void temporal_internal::model_and_departure(const float* m, const TemporalCurves* family,
                                            double first_time_s, const Series& series, int j,
                                            double* model, double* departure) {
  params_at(m, series.t[j], first_time_s, family, model);
  to_fitted_space(model);
  for (int p = 0; p < kTemporalParamCount; ++p) {
    departure[p] = significant_departure(series.y[j][p] - model[p], series.w[j][p]);
  }
}

void temporal_internal::write_modelled_steps(const std::vector<StepFit>* steps, int x, int y,
                                             TemporalMaps& band) {
  const float* m = &band.maps.at(x, y, 0);
  thread_local Series series;
  if (steps) gather_series(*steps, x, y, series, /*curves=*/true);
  int used = 0;  // The series holds the usable steps, in time order.
  for (size_t k = 0; k < band.step_times_s.size(); ++k) {
    const double t = band.step_times_s[k];
    double q[kTemporalParamCount];
    if (steps && used < series.steps && series.t[used] == t) {
      double departure[kTemporalParamCount];
      model_and_departure(m, band.curves_at(x, y), band.first_time_s(), series, used++, q,
                          departure);
      for (int p = 0; p < kTemporalParamCount; ++p) q[p] += departure[p];
    } else {
      params_at(m, t, band.first_time_s(), band.curves_at(x, y), q);
      to_fitted_space(q);
    }
    from_fitted_space(q);
    for (int p = 0; p < kTemporalParamCount; ++p) {
      band.step_values.at(x, y, int(k) * kTemporalParamCount + p) = float(q[p]);
    }
  }
}

TemporalMaps fit_temporal_models(const std::vector<StepFit>& steps, const NormalMap& normals,
                                 const TemporalFitOptions& options) {
  const auto start_time = std::chrono::steady_clock::now();
  std::vector<double> best_bic;
  TemporalMaps out = fit_temporal_processes(steps, normals, options, best_bic);
  if (options.fit_curves) {
    CurveSample sample;
    sample.count(out.maps);
    sample.gather(steps, out.maps);
    offer_temporal_curves(steps, best_bic, sample.learn(out.step_times_s), out);
  }
  hold_out_steps(steps, options, out);
  count_temporal_models(steps, out);
  out.summary.seconds_temporal =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  return out;
}

}  // namespace ls::relight
