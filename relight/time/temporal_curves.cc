// Data-driven temporal curves (relight/time/temporal_fit.h, TemporalCurves): evaluation, learning
// from a sample of pixels, one pixel's warp and endpoints under them, the families, offering them
// to the pixels (after the processes, temporal_models.cc), and any model's parameters at a time.
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <vector>

#include "relight/time/temporal_fit.h"
#include "relight/time/temporal_fit_internal.h"

namespace ls::relight {

int TemporalCurves::weights(double tau, int n, double w[4]) {
  // Catmull-Rom through knots at tau_k = k / (n - 1); the end knots repeated beyond the ends.
  const double u = std::clamp(tau, 0.0, 1.0) * (n - 1);
  const int k = std::clamp(int(std::floor(u)), 0, n - 2);
  const double f = u - k, f2 = f * f, f3 = f2 * f;
  w[0] = 0.5 * (-f + 2 * f2 - f3);
  w[1] = 0.5 * (2 - 5 * f2 + 3 * f3);
  w[2] = 0.5 * (f + 4 * f2 - 3 * f3);
  w[3] = 0.5 * (-f2 + f3);
  return k - 1;  // Knot of w[0]; indices outside [0, n) stand for the end knot.
}

double TemporalCurves::at(int p, double tau) const {
  const std::vector<double>& c = knots[size_t(p)];
  const int n = int(c.size());
  double w[4];
  const int first = weights(tau, n, w);
  double v = 0;
  for (int j = 0; j < 4; ++j) v += w[j] * c[size_t(std::clamp(first + j, 0, n - 1))];
  return v;
}

namespace temporal_internal {
namespace {

// The warp grid around the identity (tau from 0 at the first step to 1 at the last): rates as a
// factor of 1 / span, onsets as a share of the span from the first step.
constexpr double kRateFactors[] = {0.5, 0.63, 0.8, 1.0, 1.25, 1.6, 2.0};
constexpr double kOnsetShares[] = {-0.5, -0.35, -0.2, -0.1, 0.0, 0.1, 0.2, 0.35, 0.5};

double chi2_at(const Series& s, const TemporalCurves& curves, double rate, double onset,
               CurveFit* out) {
  // Every parameter's curve at the steps' tau: the knots' weights are the same for all of them.
  double shapes[kTemporalParamCount][kMaxSteps];
  const int n = int(curves.knots[0].size());
  for (int i = 0; i < s.steps; ++i) {
    double w[4];
    const int first = TemporalCurves::weights(rate * (s.t[i] - onset), n, w);
    int at[4];
    for (int j = 0; j < 4; ++j) at[j] = std::clamp(first + j, 0, n - 1);
    for (int p = 0; p < kTemporalParamCount; ++p) {
      const std::vector<double>& c = curves.knots[size_t(p)];
      shapes[p][i] = w[0] * c[size_t(at[0])] + w[1] * c[size_t(at[1])] + w[2] * c[size_t(at[2])] +
                     w[3] * c[size_t(at[3])];
    }
  }
  double chi2 = 0;
  for (int p = 0; p < kTemporalParamCount; ++p) {
    const double* shape = shapes[p];
    double wet = 0, dry = 0;
    chi2 += fit_endpoints(s, p, shape, &wet, &dry);
    if (out) out->wet[p] = wet, out->dry[p] = dry;
  }
  return chi2;
}

// Rescales each curve to run over [0, 1]; a curve that barely moves becomes 1 - tau.
void normalise(TemporalCurves& curves) {
  for (std::vector<double>& c : curves.knots) {
    const auto [lo, hi] = std::minmax_element(c.begin(), c.end());
    const double low = *lo, range = *hi - *lo;
    for (size_t k = 0; k < c.size(); ++k) {
      c[k] = range > 1e-9 ? (c[k] - low) / range : 1.0 - double(k) / double(c.size() - 1);
    }
  }
}

}  // namespace

CurveFit fit_curve(const Series& series, const TemporalCurves& curves, double t_first,
                   double span) {
  CurveFit best;
  double best_rate = 1 / span, best_onset = t_first;
  for (const double f : kRateFactors) {
    for (const double g : kOnsetShares) {
      const double rate = f / span, onset = t_first + g * span;
      const double chi2 = chi2_at(series, curves, rate, onset, nullptr);
      if (chi2 < best.chi2) best.chi2 = chi2, best_rate = rate, best_onset = onset;
    }
  }
  // Two finer rounds around the best: a third of the grid's spacing, then a ninth.
  for (double step = 1.0 / 3; step > 0.1; step /= 3) {
    const double rate0 = best_rate, onset0 = best_onset;
    for (int a = -2; a <= 2; ++a) {
      for (int b = -2; b <= 2; ++b) {
        const double rate = rate0 * std::pow(1.26, a * step),
                     onset = onset0 + b * step * 0.12 * span;
        const double chi2 = chi2_at(series, curves, rate, onset, nullptr);
        if (chi2 < best.chi2) best.chi2 = chi2, best_rate = rate, best_onset = onset;
      }
    }
  }
  best.rate = best_rate;
  best.onset = best_onset;
  chi2_at(series, curves, best_rate, best_onset, &best);
  return best;
}

// Alternations of the curves and the warps, at most; each lowers the sample's chi^2.
constexpr int kMaxRounds = 60;

TemporalCurves learn_curves(const std::vector<Series>& sample, double t_first, double span,
                            int knots, const TemporalCurves* start) {
  TemporalCurves curves;
  curves.knots.assign(kTemporalParamCount, std::vector<double>(size_t(knots)));
  if (start && !start->empty() && int(start->knots[0].size()) == knots) curves = *start;
  normalise(curves);  // Without a start: 1 - tau.
  std::vector<CurveFit> fits(sample.size());
  double previous = HUGE_VAL;
  for (int round = 0; round < kMaxRounds; ++round) {
    tbb::parallel_for(size_t(0), sample.size(),
                      [&](size_t i) { fits[i] = fit_curve(sample[i], curves, t_first, span); });
    double chi2 = 0;
    for (const CurveFit& f : fits) chi2 += f.chi2;
    if (!(chi2 < previous * (1 - 1e-3))) break;  // Converged (or no longer improving).
    previous = chi2;
    // The knots of each parameter by linear least squares given the warps and endpoints:
    // y - dry = (wet - dry) sum_k B_k(tau) c_k, with a small second-difference penalty that keeps
    // knots no sample reaches near their neighbours.
    for (int p = 0; p < kTemporalParamCount; ++p) {
      Eigen::MatrixXd a = Eigen::MatrixXd::Zero(knots, knots);
      Eigen::VectorXd b = Eigen::VectorXd::Zero(knots);
      for (size_t s = 0; s < sample.size(); ++s) {
        const Series& series = sample[s];
        const double scale = fits[s].wet[p] - fits[s].dry[p];
        for (int i = 0; i < series.steps; ++i) {
          const double w2 = series.w[i][p] * series.w[i][p];
          if (!(w2 > 0)) continue;
          double w[4];
          const int first =
              TemporalCurves::weights(fits[s].rate * (series.t[i] - fits[s].onset), knots, w);
          Eigen::VectorXd row = Eigen::VectorXd::Zero(knots);
          for (int j = 0; j < 4; ++j) row(std::clamp(first + j, 0, knots - 1)) += scale * w[j];
          a += w2 * row * row.transpose();
          b += w2 * row * (series.y[i][p] - fits[s].dry[p]);
        }
      }
      const double smooth = 1e-3 * std::max(a.trace() / knots, 1e-12);
      for (int k = 1; k + 1 < knots; ++k) {
        Eigen::VectorXd d = Eigen::VectorXd::Zero(knots);
        d(k - 1) = 1, d(k) = -2, d(k + 1) = 1;
        a += smooth * d * d.transpose();
      }
      a.diagonal().array() += 1e-12 * std::max(a.trace(), 1e-300);
      const Eigen::VectorXd c = a.ldlt().solve(b);
      if (c.allFinite()) curves.knots[size_t(p)].assign(c.data(), c.data() + knots);
    }
    normalise(curves);
  }
  return curves;
}

// At most this many curve families, each learnt from at least kMinFamilySeries series of the
// sample, shared among them by this many k-means rounds after each new one.
constexpr int kMaxCurveFamilies = 6;
constexpr int kFamilyRounds = 3;

FamilyFit best_family(const Series& series, const std::vector<TemporalCurves>& families,
                      double t_first, double span) {
  FamilyFit best;
  for (size_t f = 0; f < families.size(); ++f) {
    const CurveFit fit = fit_curve(series, families[f], t_first, span);
    if (fit.chi2 < best.fit.chi2) best = {int(f), fit};
  }
  return best;
}

// The curve families of the sample (TemporalCurves): a first one from every series; while at least
// kMinFamilySeries series stay unexplained (reduced chi^2 above kUnexplainedResidual under their
// best family), a new family from those, then the series shared among the families by rounds of
// assignment (each to its best family) and learning (each family from its own series).
std::vector<TemporalCurves> learn_families(const std::vector<Series>& sample, int knots,
                                           double t_first, double span) {
  std::vector<TemporalCurves> families = {learn_curves(sample, t_first, span, knots)};
  std::vector<FamilyFit> fits(sample.size());
  const auto assign = [&] {
    tbb::parallel_for(size_t(0), sample.size(),
                      [&](size_t i) { fits[i] = best_family(sample[i], families, t_first, span); });
  };
  const auto members = [&](int family, bool only_unexplained) {
    std::vector<Series> out;
    for (size_t i = 0; i < sample.size(); ++i) {
      const double dof = std::max(1, sample[i].steps * kTemporalParamCount - kCurveParameters);
      if (only_unexplained ? fits[i].fit.chi2 > kUnexplainedResidual * dof
                           : fits[i].family == family) {
        out.push_back(sample[i]);
      }
    }
    return out;
  };
  assign();
  while (families.size() < size_t(kMaxCurveFamilies)) {
    const std::vector<Series> unexplained_series = members(-1, true);
    if (unexplained_series.size() < kMinFamilySeries) break;
    families.push_back(learn_curves(unexplained_series, t_first, span, knots));
    for (int round = 0; round < kFamilyRounds; ++round) {
      assign();
      for (size_t f = 0; f < families.size(); ++f) {
        const std::vector<Series> own = members(int(f), false);
        if (own.size() < kMinFamilySeries) continue;
        families[f] = learn_curves(own, t_first, span, knots, &families[f]);
      }
    }
    assign();
    if (members(int(families.size()) - 1, false).size() < kMinFamilySeries) {
      families.pop_back();  // The new family explains too few: the others do as well.
      break;
    }
  }
  return families;
}

namespace {

// A curve's endpoints are where it peaks and bottoms, which a pixel that sees part of the curve
// need not reach: what must stay near the data is the curve over the steps that measure each
// parameter (sampled at four times the steps; a parameter the step does not constrain, the
// roughness of a lobe with k_s = 0, leaves the curve free there), by the processes' margin
// (ParamRange::margin).
bool curve_runs_away(const Series& series, const CurveFit& f, const TemporalCurves& curves) {
  for (int p = 0; p < kTemporalParamCount; ++p) {
    const ParamRange r = range_of(series, p);
    if (!r.informed()) continue;  // No information on this parameter.
    const int samples = 4 * series.steps;
    for (int j = 0; j <= samples; ++j) {
      const double t = r.t0 + (r.t1 - r.t0) * j / samples;
      const double at = f.dry[p] + (f.wet[p] - f.dry[p]) * curves.at(p, f.rate * (t - f.onset));
      if (at < r.lo - r.margin() || at > r.hi + r.margin()) return true;
    }
  }
  return false;
}

// The data-driven curves (TemporalCurves): learnt from up to kCurveSample pixels that no process
// explains, then offered to those pixels; one takes its curve where the curve's BIC (rate, onset,
// wet and dry: the exponential's count) is lower than its process's by kCurveEvidence and its
// endpoints stay near its data. A pixel a process explains keeps it.
constexpr size_t kCurveSample = 1500;
// The curve must win by strong evidence (kCurveEvidence): a process the data follow keeps its
// model, whose rate and onset mean something; the curve is learnt from every process of the scene
// together and fits any of them a little by chance.

// A pixel that no process explains: its best leaves a reduced chi^2 above kUnexplainedResidual, or
// ran away.
bool unexplained(const float* m) {
  return m[kTStepsUsed] >= 5 &&
         (m[kTResidual] > kUnexplainedResidual || (int(m[kTFlags]) & kTemporalDegenerate) != 0);
}

// A process misses the albedo a render sees where it leaves a chi^2 above this per albedo sample
// there (7 sigma rms: the simulator's paint and dust, whose steps' fits switch between Lambert and
// Oren-Nayar at a few pixels, stay below it on all but a few; the corroding metal's one such pixel
// is far above).
constexpr double kMissedAlbedoChi2 = 50;

// A process's course at a series' steps (in the curves' space): the chi^2 of its albedo channels
// (returned) and its BIC over every parameter (*bic).
double process_in_curve_space(const Series& series, const float* m, double first_time_s,
                              double* bic) {
  const TemporalModel model = TemporalModel(int(m[kTModel]));
  double albedo_chi2 = 0, chi2 = 0;
  for (int i = 0; i < series.steps; ++i) {
    double q[kTemporalParamCount];
    params_at(m, series.t[i], first_time_s, nullptr, q);
    to_fitted_space(q);
    for (int p = 0; p < kTemporalParamCount; ++p) {
      const double r = (q[p] - series.y[i][p]) * series.w[i][p];
      chi2 += r * r;
      if (p <= kParamAlbedoB) albedo_chi2 += r * r;
    }
  }
  const int k = model == TemporalModel::kDust ? 2 + num_endpoint_params(TemporalModel::kDust)
                                              : kCurveParameters;
  *bic = chi2 + k * std::log(double(series.steps * kTemporalParamCount));
  return albedo_chi2;
}

}  // namespace

}  // namespace temporal_internal

using temporal_internal::best_family;
using temporal_internal::curve_runs_away;
using temporal_internal::CurveFit;
using temporal_internal::FamilyFit;
using temporal_internal::gather_series;
using temporal_internal::kCurveEvidence;
using temporal_internal::kCurveParameters;
using temporal_internal::kCurveSample;
using temporal_internal::kMinFamilySeries;
using temporal_internal::kMissedAlbedoChi2;
using temporal_internal::learn_families;
using temporal_internal::process_in_curve_space;
using temporal_internal::Series;
using temporal_internal::unexplained;
using temporal_internal::write_curve;

namespace {

bool curve_candidate(const float* m) {
  return int(m[kTModel]) > int(TemporalModel::kNone) && unexplained(m);
}

}  // namespace

CurveSample::CurveSample() = default;
CurveSample::~CurveSample() = default;

void CurveSample::count(const Image& maps) {
  for (size_t i = 0; i < maps.num_pixels(); ++i) {
    candidates_ += curve_candidate(&maps.pixels[i * kTemporalChannelCount]);
  }
}

void CurveSample::gather(const std::vector<StepFit>& steps, const Image& maps) {
  if (candidates_ < kMinFamilySeries) return;
  const size_t stride = (candidates_ + kCurveSample - 1) / kCurveSample;
  for (size_t i = 0; i < maps.num_pixels(); ++i) {
    if (!curve_candidate(&maps.pixels[i * kTemporalChannelCount])) continue;
    if (gathered_++ % stride != 0) continue;
    gather_series(steps, int(i % size_t(maps.width)), int(i / size_t(maps.width)),
                  series_.emplace_back(), /*curves=*/true);
  }
}

std::vector<TemporalCurves> CurveSample::learn(const std::vector<double>& step_times) const {
  if (series_.empty() || step_times.size() < 2) return {};
  const double t_first = step_times.front(), span = step_times.back() - t_first;
  if (!(span > 0)) return {};
  const int knots = std::clamp(int(step_times.size()) + 3, 5, 16);
  return learn_families(series_, knots, t_first, span);
}

void offer_temporal_curves(const std::vector<StepFit>& steps, const std::vector<double>& best_bic,
                           const std::vector<TemporalCurves>& curves, TemporalMaps& out) {
  out.curves = curves;
  if (curves.empty()) return;
  const int width = out.maps.width, pixels = width * out.maps.height;
  const double t_first = out.first_time_s(), span = out.last_time_s() - t_first;
  tbb::parallel_for(0, pixels, [&](int i) {
    float* m = &out.maps.pixels[size_t(i) * kTemporalChannelCount];
    const TemporalModel model = TemporalModel(int(m[kTModel]));
    const bool process = model == TemporalModel::kExponential || model == TemporalModel::kSigmoid ||
                         model == TemporalModel::kDust;
    if (!std::isfinite(best_bic[size_t(i)]) || !(process || unexplained(m))) return;
    thread_local Series series;
    const int flags = gather_series(steps, i % width, i / width, series, /*curves=*/true);
    // A process that follows each parameter can still miss the albedo a render sees, albedo
    // A(sigma), where the steps' fits trade the one against the other: such a pixel is offered the
    // curves too, against its process's BIC in the curves' space.
    double current_bic = best_bic[size_t(i)];
    if (!unexplained(m)) {
      const double albedo_chi2 = process_in_curve_space(series, m, t_first, &current_bic);
      if (!(albedo_chi2 > kMissedAlbedoChi2 * 3 * series.steps)) return;
    }
    const FamilyFit best = best_family(series, out.curves, t_first, span);
    const CurveFit& f = best.fit;
    const double n = double(series.steps * kTemporalParamCount);
    const double bic = f.chi2 + kCurveParameters * std::log(n);
    if (!(bic < current_bic - kCurveEvidence) ||
        curve_runs_away(series, f, out.curves[size_t(best.family)])) {
      return;
    }
    write_curve(f, best.family, t_first + span, m);
    // The BIC weight of the curve against the process it replaces.
    m[kTConfidence] = float(1 / (1 + std::exp(-0.5 * (current_bic - bic))));
    m[kTResidual] = float(f.chi2 / std::max(1.0, n - kCurveParameters));
    m[kTFlags] = float(flags);
  });
}

namespace temporal_internal {

void write_curve(const CurveFit& f, int family, double seen_until, float* m) {
  m[kTCurve] = float(family);
  m[kTCurveSeen] = float(f.rate * (seen_until - f.onset));
  m[kTModel] = float(TemporalModel::kCurve);
  m[kTRate] = float(f.rate);
  m[kTOnset] = float(f.onset);
  // In the curves' space (temporal_fit.h) and not clamped: where the curve bottoms or peaks may
  // lie beyond a parameter's bound that the curve never reaches over the span (renders clamp the
  // value at each time).
  for (int p = 0; p < kTemporalParamCount; ++p) {
    m[kTWet + p] = float(f.wet[p]);
    m[kTDry + p] = float(f.dry[p]);
  }
}

void params_at(const float* m, double t, double first_time_s, const TemporalCurves* curves,
               double* q) {
  const TemporalModel model = TemporalModel(int(m[kTModel]));
  const bool curve = model == TemporalModel::kCurve;
  if (curve && m[kTRate] > 0) {  // Within what the steps saw (kTCurveSeen).
    const double seen_until = double(m[kTOnset]) + double(m[kTCurveSeen]) / m[kTRate];
    t = std::clamp(t, first_time_s, std::max(first_time_s, seen_until));
  }
  for (int p = 0; p < kTemporalParamCount; ++p) {
    double wet = m[kTWet + p], dry = m[kTDry + p];
    const bool reciprocal = p == kParamRoughness && !curve;
    if (reciprocal) {
      wet = 1 / std::max(wet, kMinRoughness);
      dry = 1 / std::max(dry, kMinRoughness);
    }
    double v = temporal_value(model, m[kTRate], m[kTOnset], wet, dry, t, curves, p);
    if (!std::isfinite(v)) v = dry;
    q[p] = reciprocal ? (v > 0 ? 1 / v : 1.0) : v;
  }
  if (curve) {
    from_fitted_space(q);
  } else {
    for (int p = 0; p < kTemporalParamCount; ++p) q[p] = clamp_param(p, q[p]);
  }
}

}  // namespace temporal_internal

const TemporalCurves* TemporalMaps::curves_at(int x, int y) const {
  if (model(x, y) != TemporalModel::kCurve) return nullptr;
  const int family = int(maps.at(x, y, kTCurve));
  return family >= 0 && family < int(curves.size()) ? &curves[size_t(family)] : nullptr;
}

}  // namespace ls::relight
