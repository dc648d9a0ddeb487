// Temporal curve models (constant / exponential / sigmoid / dust), their fits and the BIC choice
// per pixel (relight/time/temporal_fit.h, step 3).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
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
#include "physics/brdf.h"
#include "relight/fit/pixel_solver.h"
#include "relight/time/temporal_fit.h"
#include "relight/time/temporal_fit_internal.h"

namespace ls::relight {
namespace {

using pixel::SolverStatus;
using temporal_internal::clamp_param;
using temporal_internal::kMaxSigma;
using temporal_internal::kMaxSteps;
using temporal_internal::kMinRoughness;
using temporal_internal::kNoInformationSigma;
using temporal_internal::num_endpoint_params;
using temporal_internal::Series;

// ---------------------------------------------------------------------------------------------
// Temporal models. Each parameter j follows p_j(t) = dry_j + (wet_j - dry_j) s(t), s = 1 at the
// wet end, 0 at the dry end (the roughness series is fitted as 1/m: harmonic in the weight, as
// the paint model of the paper).

template <class T>
T shape_weight(TemporalModel model, const T& rate, const T& onset, double t) {
  using std::exp;
  switch (model) {
    case TemporalModel::kExponential:
    case TemporalModel::kDust:
      return T(t) < onset ? T(1) : exp(-rate * (T(t) - onset));
    case TemporalModel::kSigmoid:
      return T(1) / (T(1) + exp(rate * (T(t) - onset)));
    default:
      return T(0);
  }
}

// Which parameters move under each model (dust: k_s decays to 0, sigma and roughness constant).
bool param_moves(TemporalModel model, int p) {
  if (model == TemporalModel::kConstant || model == TemporalModel::kNone) return false;
  if (model == TemporalModel::kDust) return p <= kParamAlbedoB || p == kParamKs;
  return true;
}
bool dry_pinned_to_zero(TemporalModel model, int p) {
  return model == TemporalModel::kDust && p == kParamKs;
}

// Bounds of the nonlinear parameters.
struct ShapeBounds {
  double log_rate_lo, log_rate_hi;
  double onset_lo, onset_hi;
};

// Endpoints linear given the shape; returns chi^2 and fills wet/dry.
double solve_endpoints(TemporalModel model, const Series& s, double rate, double onset, double* wet,
                       double* dry) {
  double chi2 = 0;
  double shape[kMaxSteps];
  for (int i = 0; i < s.steps; ++i) shape[i] = shape_weight(model, rate, onset, s.t[i]);
  for (int p = 0; p < kTemporalParamCount; ++p) {
    if (!param_moves(model, p)) {
      double sw = 0, swy = 0;
      for (int i = 0; i < s.steps; ++i) {
        sw += s.w[i][p] * s.w[i][p];
        swy += s.w[i][p] * s.w[i][p] * s.y[i][p];
      }
      wet[p] = dry[p] = sw > 0 ? swy / sw : 0;
    } else if (dry_pinned_to_zero(model, p)) {
      double saa = 0, say = 0;
      for (int i = 0; i < s.steps; ++i) {
        const double w2 = s.w[i][p] * s.w[i][p];
        saa += w2 * shape[i] * shape[i];
        say += w2 * shape[i] * s.y[i][p];
      }
      dry[p] = 0;
      wet[p] = saa > 1e-300 ? say / saa : 0;
    } else {
      chi2 += temporal_internal::fit_endpoints(s, p, shape, &wet[p], &dry[p]);
      continue;
    }
    for (int i = 0; i < s.steps; ++i) {
      const double r = (dry[p] + (wet[p] - dry[p]) * shape[i] - s.y[i][p]) * s.w[i][p];
      chi2 += r * r;
    }
  }
  return chi2;
}

// x = [u_rate, u_onset, endpoints...]; endpoints in parameter order, wet then dry for a moving
// parameter, one value for a constant one, wet only for a k_s pinned at 0.
template <TemporalModel M>
struct TemporalCost {
  const Series* s;
  ShapeBounds bounds;
  int NumResiduals() const { return s->steps * kTemporalParamCount; }
  template <class T>
  void unpack(const T* x, T* rate, T* onset, T* wet, T* dry) const {
    using std::exp;
    *rate = exp(pixel::bounded(x[0], bounds.log_rate_lo, bounds.log_rate_hi));
    *onset = pixel::bounded(x[1], bounds.onset_lo, bounds.onset_hi);
    int k = 2;
    for (int p = 0; p < kTemporalParamCount; ++p) {
      if (!param_moves(M, p)) {
        wet[p] = dry[p] = x[k++];
      } else if (dry_pinned_to_zero(M, p)) {
        wet[p] = x[k++];
        dry[p] = T(0);
      } else {
        wet[p] = x[k++];
        dry[p] = x[k++];
      }
    }
  }
  template <class T>
  bool operator()(const T* x, T* r) const {
    T rate, onset, wet[kTemporalParamCount], dry[kTemporalParamCount];
    unpack(x, &rate, &onset, wet, dry);
    for (int i = 0; i < s->steps; ++i) {
      const T shape = shape_weight(M, rate, onset, s->t[i]);
      for (int p = 0; p < kTemporalParamCount; ++p) {
        r[i * kTemporalParamCount + p] =
            (dry[p] + (wet[p] - dry[p]) * shape - T(s->y[i][p])) * T(s->w[i][p]);
      }
    }
    return true;
  }
};

struct TemporalResult {
  bool ok = false;
  SolverStatus status = SolverStatus::kConverged;  // Of the LM refinement (none: closed form).
  double chi2 = std::numeric_limits<double>::infinity();
  int k = 0;
  double rate = 0, onset = 0;
  double wet[kTemporalParamCount] = {}, dry[kTemporalParamCount] = {};
};

template <TemporalModel M>
TemporalResult fit_process(const Series& s, const ShapeBounds& bounds, int iterations) {
  constexpr int K = 2 + num_endpoint_params(M);
  TemporalResult best;
  best.k = K;
  // Grid start: rates log-spaced over the bounds, onsets at the steps and between them.
  std::vector<double> onsets;
  for (int i = 0; i < s.steps; ++i) {
    onsets.push_back(s.t[i]);
    if (i + 1 < s.steps) onsets.push_back(0.5 * (s.t[i] + s.t[i + 1]));
  }
  for (double& o : onsets) o = std::clamp(o, bounds.onset_lo, bounds.onset_hi);
  constexpr int kRates = 14;
  double grid_rate = 0, grid_onset = 0, grid_chi2 = std::numeric_limits<double>::infinity();
  double wet[kTemporalParamCount], dry[kTemporalParamCount];
  for (int r = 0; r < kRates; ++r) {
    const double rate = std::exp(bounds.log_rate_lo +
                                 (bounds.log_rate_hi - bounds.log_rate_lo) * (r + 0.5) / kRates);
    for (const double onset : onsets) {
      const double chi2 = solve_endpoints(M, s, rate, onset, wet, dry);
      if (chi2 < grid_chi2) {
        grid_chi2 = chi2;
        grid_rate = rate;
        grid_onset = onset;
      }
    }
  }
  if (!std::isfinite(grid_chi2)) return best;
  solve_endpoints(M, s, grid_rate, grid_onset, wet, dry);
  Eigen::Matrix<double, K, 1> x;
  x(0) =
      pixel::clamped_bounded_inverse(std::log(grid_rate), bounds.log_rate_lo, bounds.log_rate_hi);
  x(1) = bounds.onset_hi > bounds.onset_lo
             ? pixel::clamped_bounded_inverse(grid_onset, bounds.onset_lo, bounds.onset_hi)
             : 0.0;
  int k = 2;
  for (int p = 0; p < kTemporalParamCount; ++p) {
    if (!param_moves(M, p)) {
      x(k++) = wet[p];
    } else if (dry_pinned_to_zero(M, p)) {
      x(k++) = wet[p];
    } else {
      x(k++) = wet[p];
      x(k++) = dry[p];
    }
  }
  const TemporalCost<M> cost{&s, bounds};
  const pixel::SolveResult<K> solved = pixel::solve(cost, x, iterations);
  best.status = solved.status;
  double chi2 = solved.chi2;
  if (!std::isfinite(chi2) || chi2 > pixel::chi2_at(cost, x.data())) {
    chi2 = pixel::chi2_at(cost, x.data());  // Never worse than the grid start.
  } else {
    x = solved.x;
  }
  if (!std::isfinite(chi2)) return best;
  cost.unpack(x.data(), &best.rate, &best.onset, best.wet, best.dry);
  best.chi2 = chi2;
  best.ok = std::isfinite(best.rate) && std::isfinite(best.onset);
  for (int p = 0; p < kTemporalParamCount; ++p) {
    best.ok = best.ok && std::isfinite(best.wet[p]) && std::isfinite(best.dry[p]);
  }
  return best;
}

TemporalResult fit_constant(const Series& s) {
  TemporalResult out;
  out.k = kTemporalParamCount;
  out.chi2 = solve_endpoints(TemporalModel::kConstant, s, 0, 0, out.wet, out.dry);
  out.ok = std::isfinite(out.chi2);
  return out;
}

// Converts a series value back from the processes' space (roughness is fitted as 1/m).
double to_physical(int p, double v) {
  if (p == kParamRoughness) return v > 1.0 ? 1.0 / v : 1.0;  // 1/m >= 1 for m <= 1.
  return v;
}

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
    fits[2] = fit_process<TemporalModel::kExponential>(series, c.bounds, c.options.max_iterations);
  }
  if (enough && c.options.fit_sigmoid) {
    fits[3] = fit_process<TemporalModel::kSigmoid>(series, c.bounds, c.options.max_iterations);
  }
  if (enough && c.options.fit_dust) {
    fits[4] = fit_process<TemporalModel::kDust>(series, c.bounds, c.options.max_iterations);
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
  m[kTModel] = float(best);
  m[kTRate] = model == TemporalModel::kConstant ? 0.0f : float(f.rate);
  m[kTOnset] = model == TemporalModel::kConstant ? float(c.t_first) : float(f.onset);
  for (int p = 0; p < kTemporalParamCount; ++p) {
    m[kTWet + p] = float(clamp_param(p, to_physical(p, f.wet[p])));
    m[kTDry + p] = float(clamp_param(p, to_physical(p, f.dry[p])));
  }
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
  double min_interval = std::numeric_limits<double>::infinity();
  for (size_t i = 1; i < steps.size(); ++i) {
    min_interval = std::min(min_interval, steps[i].time_s - steps[i - 1].time_s);
  }
  const double span = t_last - t_first;
  ShapeBounds bounds{};
  if (steps.size() > 1) {
    bounds.log_rate_hi = std::log(options.max_rate_times_interval / min_interval);
    // Slowest: 5% of the change over 100 capture spans (indistinguishable from constant).
    bounds.log_rate_lo = std::log(0.05 / (100 * span));
    bounds.onset_lo = t_first;
    bounds.onset_hi = t_last;
  }
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
          continue;
        }
        for (int c = 0; c < 3; ++c) m[kTNormalX + c] = normals.normal.at(x, y, c);
        flags |= temporal_internal::gather_series(steps, x, y, series);
        if (series.steps == 0) {
          m[kTFlags] = float(flags | kTemporalFitFailed);
          ++local.flagged;
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
  });
  return out;
}

void count_temporal_models(const std::vector<StepFit>& steps, TemporalMaps& band) {
  const int width = band.maps.width, height = band.maps.height;
  TemporalSummary& summary = band.summary;
  std::fill(std::begin(summary.per_model), std::end(summary.per_model), 0);
  summary.faster_than_sampling = summary.too_few_steps = summary.step_dropped = 0;
  summary.not_converged = 0;
  std::vector<int> degenerate;
  for (int i = 0; i < width * height; ++i) {
    const float* m = &band.maps.pixels[size_t(i) * kTemporalChannelCount];
    const int model = int(m[kTModel]), flags = int(m[kTFlags]);
    if (model == 0) continue;
    ++summary.per_model[model];
    summary.faster_than_sampling += (flags & kFasterThanSampling) != 0;
    summary.too_few_steps += (flags & kTooFewSteps) != 0;
    summary.step_dropped += (flags & kStepDropped) != 0;
    summary.not_converged += (flags & kTemporalNotConverged) != 0;
    if (flags & kTemporalDegenerate) degenerate.push_back(i);
  }
  summary.degenerate = int(degenerate.size());
  summary.curve_families = int(band.curves.size());
  band.step_values =
      degenerate.empty() ? Image{} : step_values_of(steps, degenerate, width, height);
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
  count_temporal_models(steps, out);
  out.summary.seconds_temporal =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  return out;
}

}  // namespace ls::relight
