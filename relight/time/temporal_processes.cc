// The processes of the temporal fit (relight/time/temporal_fit.h, step 3): constant, exponential,
// sigmoid and dust, each fitted to one pixel's series by bounded weighted least squares.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "relight/fit/pixel_solver.h"
#include "relight/time/temporal_fit_internal.h"

namespace ls::relight::temporal_internal {
namespace {

// ---------------------------------------------------------------------------------------------
// Temporal models. Each parameter j follows p_j(t) = dry_j + (wet_j - dry_j) s(t), s = 1 at the
// wet end, 0 at the dry end (the roughness series is fitted as 1/m: harmonic in the weight, as
// the paint model of the paper).

template <class T>
T shape_at(TemporalModel model, const T& rate, const T& onset, double t) {
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

// Endpoints linear given the shape; returns chi^2 and fills wet/dry.
double solve_endpoints(TemporalModel model, const Series& s, double rate, double onset, double* wet,
                       double* dry) {
  double chi2 = 0;
  double shape[kMaxSteps];
  for (int i = 0; i < s.steps; ++i) shape[i] = shape_at(model, rate, onset, s.t[i]);
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
      const T shape = shape_at(M, rate, onset, s->t[i]);
      for (int p = 0; p < kTemporalParamCount; ++p) {
        r[i * kTemporalParamCount + p] =
            (dry[p] + (wet[p] - dry[p]) * shape - T(s->y[i][p])) * T(s->w[i][p]);
      }
    }
    return true;
  }
};

// Grid start: rates log-spaced over the bounds, onsets at the steps and between them; the best
// point's chi^2 (infinite: none), its rate and onset.
double grid_start(TemporalModel model, const Series& s, const ShapeBounds& bounds,
                  double* best_rate, double* best_onset) {
  std::vector<double> onsets;
  for (int i = 0; i < s.steps; ++i) {
    onsets.push_back(s.t[i]);
    if (i + 1 < s.steps) onsets.push_back(0.5 * (s.t[i] + s.t[i + 1]));
  }
  for (double& o : onsets) o = std::clamp(o, bounds.onset_lo, bounds.onset_hi);
  constexpr int kRates = 14;
  double best = std::numeric_limits<double>::infinity();
  double wet[kTemporalParamCount], dry[kTemporalParamCount];
  for (int r = 0; r < kRates; ++r) {
    const double rate = std::exp(bounds.log_rate_lo +
                                 (bounds.log_rate_hi - bounds.log_rate_lo) * (r + 0.5) / kRates);
    for (const double onset : onsets) {
      const double chi2 = solve_endpoints(model, s, rate, onset, wet, dry);
      if (chi2 < best) {
        best = chi2;
        *best_rate = rate;
        *best_onset = onset;
      }
    }
  }
  return best;
}

template <TemporalModel M>
TemporalResult fit_process_of(const Series& s, const ShapeBounds& bounds, int iterations,
                              const TemporalResult* start) {
  constexpr int K = 2 + num_endpoint_params(M);
  TemporalResult best;
  best.k = K;
  double grid_rate = 0, grid_onset = 0;
  double wet[kTemporalParamCount], dry[kTemporalParamCount];
  if (start != nullptr) {  // From a fit of the same model (to data that differ little).
    grid_rate = std::clamp(start->rate, std::exp(bounds.log_rate_lo), std::exp(bounds.log_rate_hi));
    grid_onset = std::clamp(start->onset, bounds.onset_lo, bounds.onset_hi);
    std::copy_n(start->wet, kTemporalParamCount, wet);
    std::copy_n(start->dry, kTemporalParamCount, dry);
  } else {
    if (!std::isfinite(grid_start(M, s, bounds, &grid_rate, &grid_onset))) return best;
    solve_endpoints(M, s, grid_rate, grid_onset, wet, dry);
  }
  Eigen::Matrix<double, K, 1> x;
  x(0) =
      pixel::clamped_bounded_inverse(std::log(grid_rate), bounds.log_rate_lo, bounds.log_rate_hi);
  x(1) = bounds.onset_hi > bounds.onset_lo
             ? pixel::clamped_bounded_inverse(grid_onset, bounds.onset_lo, bounds.onset_hi)
             : 0.0;
  int k = 2;
  for (int p = 0; p < kTemporalParamCount; ++p) {
    x(k++) = wet[p];  // A constant parameter's value, or its wet end.
    if (param_moves(M, p) && !dry_pinned_to_zero(M, p)) x(k++) = dry[p];
  }
  const TemporalCost<M> cost{&s, bounds};
  const pixel::SolveResult<K> solved = pixel::solve(cost, x, iterations);
  best.status = solved.status;
  double chi2 = solved.chi2;
  if (!std::isfinite(chi2) || chi2 > pixel::chi2_at(cost, x.data())) {
    chi2 = pixel::chi2_at(cost, x.data());  // Never worse than the start.
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

}  // namespace

double shape_weight(TemporalModel model, double rate, double onset, double t) {
  return shape_at(model, rate, onset, t);
}

ShapeBounds shape_bounds(const std::vector<double>& step_times, double max_rate_times_interval) {
  ShapeBounds bounds{};
  if (step_times.size() < 2) return bounds;
  double min_interval = std::numeric_limits<double>::infinity();
  for (size_t i = 1; i < step_times.size(); ++i) {
    min_interval = std::min(min_interval, step_times[i] - step_times[i - 1]);
  }
  const double span = step_times.back() - step_times.front();
  bounds.log_rate_hi = std::log(max_rate_times_interval / min_interval);
  // Slowest: 5% of the change over 100 capture spans (indistinguishable from constant).
  bounds.log_rate_lo = std::log(0.05 / (100 * span));
  bounds.onset_lo = step_times.front();
  bounds.onset_hi = step_times.back();
  return bounds;
}

TemporalResult fit_process(TemporalModel model, const Series& s, const ShapeBounds& bounds,
                           int iterations, const TemporalResult* start) {
  switch (model) {
    case TemporalModel::kExponential:
      return fit_process_of<TemporalModel::kExponential>(s, bounds, iterations, start);
    case TemporalModel::kSigmoid:
      return fit_process_of<TemporalModel::kSigmoid>(s, bounds, iterations, start);
    case TemporalModel::kDust:
      return fit_process_of<TemporalModel::kDust>(s, bounds, iterations, start);
    default:
      return fit_constant(s);
  }
}

TemporalResult fit_constant(const Series& s) {
  TemporalResult out;
  out.k = kTemporalParamCount;
  out.chi2 = solve_endpoints(TemporalModel::kConstant, s, 0, 0, out.wet, out.dry);
  out.ok = std::isfinite(out.chi2);
  return out;
}

void write_process(TemporalModel model, const TemporalResult& f, double t_first, float* m) {
  const bool constant = model == TemporalModel::kConstant;
  m[kTModel] = float(model);
  m[kTRate] = constant ? 0.0f : float(f.rate);
  m[kTOnset] = constant ? float(t_first) : float(f.onset);
  for (int p = 0; p < kTemporalParamCount; ++p) {
    m[kTWet + p] = float(clamp_param(p, to_physical(p, f.wet[p])));
    m[kTDry + p] = float(clamp_param(p, to_physical(p, f.dry[p])));
  }
}

void interpolate_params(const double* a, const double* b, double w, double* q) {
  for (int p = 0; p < kTemporalParamCount; ++p) q[p] = (1 - w) * a[p] + w * b[p];
  const double ma = a[kParamKs] > 0 ? a[kParamRoughness] : b[kParamRoughness];
  const double mb = b[kParamKs] > 0 ? b[kParamRoughness] : ma;
  q[kParamRoughness] = clamp_param(kParamRoughness, (1 - w) * ma + w * mb);
}

// Converts a series value back from the processes' space (roughness is fitted as 1/m).
double to_physical(int p, double v) {
  if (p == kParamRoughness) return v > 1.0 ? 1.0 / v : 1.0;  // 1/m >= 1 for m <= 1.
  return v;
}
}  // namespace ls::relight::temporal_internal
