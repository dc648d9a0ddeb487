#include "relight/temporal_fit.h"

#include <OpenImageIO/imageio.h>
#include <ceres/tiny_solver.h>
#include <ceres/tiny_solver_autodiff_function.h>
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
#include <nlohmann/json.hpp>
#include <sstream>

#include "lightstage/errors.h"
#include "relight/brdf.h"

namespace ls::relight {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kLuma[3] = {0.2126, 0.7152, 0.0722};
constexpr double kMinRoughness = 0.02;
constexpr double kMaxSigma = 0.5 * kPi;
constexpr const char* kTemporalAttribute = "lightstage:temporal";
// Standard deviation standing for "no information" (a parameter the step does not constrain, e.g.
// the roughness of a lobe with k_s = 0): weight 1e-12, i.e. none.
constexpr double kNoInformationSigma = 1e6;

template <class T>
T sigmoid(const T& u) {
  using std::exp;
  return T(1) / (T(1) + exp(-u));
}
double logit(double p) {
  p = std::clamp(p, 1e-4, 1 - 1e-4);
  return std::log(p / (1 - p));
}

// ---------------------------------------------------------------------------------------------
// Per-step BRDF fit with a fixed normal: Oren-Nayar diffuse + white Torrance-Sparrow lobe.

struct Sample {
  Eigen::Vector3d l;  // Unit, toward the LED.
  double v[3];        // Measured R per channel.
  double inv_sigma[3];
};

struct StepPixel {
  const Sample* samples = nullptr;
  int count = 0;
  Eigen::Vector3d n, wo;
};

// Residuals of the physical parameters q = (albedo r, g, b, sigma, k_s, roughness).
template <class T>
void step_residuals(const StepPixel& d, const T* q, T* r) {
  const brdf::Vec3<T> n = d.n.cast<T>();
  const brdf::Vec3<T> wo = d.wo.cast<T>();
  for (int i = 0; i < d.count; ++i) {
    const Sample& s = d.samples[i];
    const auto g = brdf::Geometry<T>::from_world(n, s.l.cast<T>(), wo);
    const T diffuse = brdf::oren_nayar(g, q[3]);
    const T specular = q[4] * brdf::torrance_sparrow(g, q[5]);
    const T cos_i = g.cos_i > T(0) ? g.cos_i : T(0);
    for (int c = 0; c < 3; ++c) {
      r[3 * i + c] = ((q[c] * diffuse + specular) * cos_i - T(s.v[c])) * T(s.inv_sigma[c]);
    }
  }
}

// Raw parameters with the bounds built in: albedo = u^2, then (Oren-Nayar) sigma = (pi/2)
// sigmoid(u), then (lobe) k_s = u^2, roughness = 0.02 + 0.98 sigmoid(u). A parameter the model
// leaves out is fixed: sigma = 0 (Lambert), k_s = 0 (no lobe).
template <bool kOrenNayar, bool kLobe>
struct StepCostRaw {
  static constexpr int kParams = 3 + (kOrenNayar ? 1 : 0) + (kLobe ? 2 : 0);
  const StepPixel* d;
  int NumResiduals() const { return 3 * d->count; }
  template <class T>
  static void physical(const T* u, T* q) {
    q[0] = u[0] * u[0];
    q[1] = u[1] * u[1];
    q[2] = u[2] * u[2];
    q[3] = T(0);
    q[4] = T(0);
    q[5] = T(0.3);
    int k = 3;
    if constexpr (kOrenNayar) q[3] = T(kMaxSigma) * sigmoid(u[k++]);
    if constexpr (kLobe) {
      q[4] = u[k] * u[k];
      q[5] = T(kMinRoughness) + T(1 - kMinRoughness) * sigmoid(u[k + 1]);
    }
  }
  template <class T>
  bool operator()(const T* u, T* r) const {
    T q[6];
    physical(u, q);
    step_residuals(*d, q, r);
    return true;
  }
};

struct StepCostPhysical {
  const StepPixel* d;
  int NumResiduals() const { return 3 * d->count; }
  template <class T>
  bool operator()(const T* q, T* r) const {
    step_residuals(*d, q, r);
    return true;
  }
};

struct StepResult {
  bool ok = false;
  double chi2 = std::numeric_limits<double>::infinity();
  std::array<double, 6> q{};
  std::array<bool, 6> used{};  // Parameters the model fitted (the others are fixed).
  int k = 0;
};

template <bool kOrenNayar, bool kLobe>
StepResult solve_step(const StepPixel& d, const std::array<double, 6>& start, int iterations) {
  using Cost = StepCostRaw<kOrenNayar, kLobe>;
  constexpr int K = Cost::kParams;
  using Function = ceres::TinySolverAutoDiffFunction<Cost, Eigen::Dynamic, K>;
  const Cost cost{&d};
  const Function function(cost);
  ceres::TinySolver<Function> solver;
  solver.options.max_num_iterations = iterations;
  Eigen::Matrix<double, K, 1> u;
  for (int c = 0; c < 3; ++c) u(c) = std::sqrt(std::max(start[c], 1e-6));
  int k = 3;
  if constexpr (kOrenNayar) u(k++) = logit(std::max(start[3], 0.05) / kMaxSigma);
  if constexpr (kLobe) {
    u(k) = std::sqrt(std::max(start[4], 1e-6));
    u(k + 1) = logit((start[5] - kMinRoughness) / (1 - kMinRoughness));
  }
  solver.Solve(function, &u);
  StepResult out;
  out.k = K;
  out.used = {true, true, true, kOrenNayar, kLobe, kLobe};
  if (!u.allFinite()) return out;
  Cost::physical(u.data(), out.q.data());
  thread_local std::vector<double> residuals;
  residuals.resize(size_t(cost.NumResiduals()));
  cost(u.data(), residuals.data());
  double chi2 = 0;
  for (const double r : residuals) chi2 += r * r;
  out.chi2 = chi2;
  out.ok = std::isfinite(chi2);
  for (const double v : out.q) out.ok = out.ok && std::isfinite(v);
  return out;
}

// Standard deviations of the physical parameters at q: the fitted ones from sqrt(diag((J^T
// J)^-1)) over the fitted parameters only, times max(1, chi2/dof); a fixed one (sigma = 0, k_s =
// 0) from its conditional deviation 1 / sqrt(J_p^T J_p) (sigma's column vanishes at 0: no
// information); the roughness of an absent lobe carries none. Floored at kParamSigmaFloor.
// Why only the fitted block: a wide lobe trades off against the albedo (and sigma against the
// albedo where the view is along the normal), so the full 6x6 inverse would call a well-measured
// Lambertian albedo unconstrained.
std::array<double, 6> step_sigmas(const StepPixel& d, const StepResult& fit) {
  using Function = ceres::TinySolverAutoDiffFunction<StepCostPhysical, Eigen::Dynamic, 6>;
  const StepCostPhysical cost{&d};
  const Function function(cost);
  const int n = cost.NumResiduals();
  Eigen::VectorXd residuals(n);
  Eigen::MatrixXd jacobian(n, 6);
  std::array<double, 6> sigmas;
  sigmas.fill(kNoInformationSigma);
  if (!function(fit.q.data(), residuals.data(), jacobian.data()) || !jacobian.allFinite()) {
    return sigmas;
  }
  const Eigen::Matrix<double, 6, 6> jtj = jacobian.transpose() * jacobian;
  std::vector<int> used;
  for (int p = 0; p < 6; ++p) {
    if (fit.used[p]) used.push_back(p);
  }
  const int k = int(used.size());
  Eigen::MatrixXd block(k, k);
  for (int i = 0; i < k; ++i) {
    for (int j = 0; j < k; ++j) block(i, j) = jtj(used[i], used[j]);
  }
  const double ridge = 1e-10 * std::max(1.0, block.diagonal().maxCoeff());
  block.diagonal().array() += ridge;
  const Eigen::MatrixXd covariance = block.ldlt().solve(Eigen::MatrixXd::Identity(k, k));
  const int dof = n - k;
  const double scale = std::max(1.0, dof > 0 ? fit.chi2 / dof : 1.0);
  std::array<double, 6> variance;
  for (int p = 0; p < 6; ++p) variance[p] = 1 / (jtj(p, p) + ridge);
  for (int i = 0; i < k; ++i) variance[used[i]] = covariance(i, i);
  for (int p = 0; p < 6; ++p) {
    const double v = variance[p] * scale;
    sigmas[p] = std::isfinite(v) && v > 0 ? std::sqrt(v) : kNoInformationSigma;
    sigmas[p] = std::clamp(sigmas[p], kParamSigmaFloor[p], kNoInformationSigma);
  }
  if (!fit.used[kParamRoughness]) sigmas[kParamRoughness] = kNoInformationSigma;
  return sigmas;
}

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

struct Series {
  int steps = 0;  // Usable steps.
  double t[64];
  double y[64][kTemporalParamCount];
  double w[64][kTemporalParamCount];  // 1 / sigma, 0 = no information.
};
constexpr int kMaxSteps = 64;

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
      // Basis (1 - s, s) for (dry, wet); a tiny ridge keeps it solvable when s is the same at
      // every step (then wet and dry are equal, the ridge decides).
      Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
      Eigen::Vector2d b = Eigen::Vector2d::Zero();
      for (int i = 0; i < s.steps; ++i) {
        const double w2 = s.w[i][p] * s.w[i][p];
        const Eigen::Vector2d basis(1 - shape[i], shape[i]);
        a += w2 * basis * basis.transpose();
        b += w2 * basis * s.y[i][p];
      }
      const double ridge = 1e-9 * std::max(a.trace(), 1e-300);
      a(0, 0) += ridge;
      a(1, 1) += ridge;
      a(0, 1) -= ridge;
      a(1, 0) -= ridge;  // Pulls wet toward dry, not toward 0.
      const Eigen::Vector2d x = a.ldlt().solve(b);
      dry[p] = std::isfinite(x(0)) ? x(0) : 0;
      wet[p] = std::isfinite(x(1)) ? x(1) : dry[p];
    }
    for (int i = 0; i < s.steps; ++i) {
      const double r = (dry[p] + (wet[p] - dry[p]) * shape[i] - s.y[i][p]) * s.w[i][p];
      chi2 += r * r;
    }
  }
  return chi2;
}

constexpr int num_endpoint_params(TemporalModel model) {
  return model == TemporalModel::kDust ? 9 : 2 * kTemporalParamCount;
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
    *rate = exp(T(bounds.log_rate_lo) + T(bounds.log_rate_hi - bounds.log_rate_lo) * sigmoid(x[0]));
    *onset = T(bounds.onset_lo) + T(bounds.onset_hi - bounds.onset_lo) * sigmoid(x[1]);
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
      logit((std::log(grid_rate) - bounds.log_rate_lo) / (bounds.log_rate_hi - bounds.log_rate_lo));
  x(1) = bounds.onset_hi > bounds.onset_lo
             ? logit((grid_onset - bounds.onset_lo) / (bounds.onset_hi - bounds.onset_lo))
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
  using Function = ceres::TinySolverAutoDiffFunction<TemporalCost<M>, Eigen::Dynamic, K>;
  const TemporalCost<M> cost{&s, bounds};
  const Function function(cost);
  ceres::TinySolver<Function> solver;
  solver.options.max_num_iterations = iterations;
  const Eigen::Matrix<double, K, 1> x_grid = x;
  solver.Solve(function, &x);
  auto chi2_at = [&](const Eigen::Matrix<double, K, 1>& v) {
    thread_local std::vector<double> residuals;
    residuals.resize(size_t(cost.NumResiduals()));
    cost(v.data(), residuals.data());
    double chi2 = 0;
    for (const double r : residuals) chi2 += r * r;
    return chi2;
  };
  double chi2 = x.allFinite() ? chi2_at(x) : std::numeric_limits<double>::infinity();
  if (!std::isfinite(chi2) || chi2 > chi2_at(x_grid)) {  // Never worse than the grid start.
    x = x_grid;
    chi2 = chi2_at(x);
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

// Converts a series value back from the fitted space (roughness is fitted as 1/m).
double to_physical(int p, double v) {
  if (p == kParamRoughness) return v > 1.0 ? 1.0 / v : 1.0;  // 1/m >= 1 for m <= 1.
  return v;
}

double clamp_param(int p, double v) {
  switch (p) {
    case kParamSigma:
      return std::clamp(v, 0.0, kMaxSigma);
    case kParamRoughness:
      return std::clamp(v, kMinRoughness, 1.0);
    default:
      return std::max(v, 0.0);
  }
}

// Field with every step's lights side by side (for pooled photometric stereo).
capture::ReflectanceField pooled_field(const std::vector<const capture::ReflectanceField*>& steps) {
  std::vector<capture::FieldLight> lights;
  for (auto* f : steps) lights.insert(lights.end(), f->lights().begin(), f->lights().end());
  capture::ReflectanceField pooled(steps[0]->width(), steps[0]->height(), lights);
  for (int y = 0; y < pooled.height(); ++y) {
    for (int x = 0; x < pooled.width(); ++x) {
      float* out = pooled.pixel(x, y);
      for (auto* f : steps)
        out = std::copy(f->pixel(x, y), f->pixel(x, y) + 3 * f->num_lights(), out);
    }
  }
  return pooled;
}

NormalMap normals_from(const std::vector<const capture::ReflectanceField*>& sorted,
                       const NormalOptions& options, NormalSource source) {
  if (source == NormalSource::kPooled && sorted.size() > 1) {
    return estimate_normals(pooled_field(sorted), options);
  }
  return estimate_normals(source == NormalSource::kLast ? *sorted.back() : *sorted.front(),
                          options);
}

void check_same_layout(const std::vector<capture::ReflectanceField>& steps) {
  if (steps.empty()) throw InputError("temporal fit: expected at least one field, got none");
  const auto& a = steps[0];
  for (const auto& f : steps) {
    if (f.width() != a.width() || f.height() != a.height()) {
      throw InputError(f.source + ": size: expected " + std::to_string(a.width()) + "x" +
                       std::to_string(a.height()) + " (as " + a.source + "), got " +
                       std::to_string(f.width()) + "x" + std::to_string(f.height()));
    }
    if (!std::isfinite(f.scene_time_s)) {
      throw InputError(f.source + ": scene_time_s: expected a finite time");
    }
  }
}

}  // namespace

const char* to_string(TemporalModel model) {
  switch (model) {
    case TemporalModel::kNone:
      return "none";
    case TemporalModel::kConstant:
      return "constant";
    case TemporalModel::kExponential:
      return "exponential";
    case TemporalModel::kSigmoid:
      return "sigmoid";
    case TemporalModel::kDust:
      return "dust";
  }
  return "?";
}

const char* temporal_param_name(int param) {
  static const char* names[kTemporalParamCount] = {"albedo.r", "albedo.g", "albedo.b",
                                                   "sigma",    "ks",       "roughness"};
  return param >= 0 && param < kTemporalParamCount ? names[param] : "?";
}

const std::vector<std::string>& temporal_channel_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n = {"normal.x", "normal.y", "normal.z", "model", "rate", "onset"};
    for (int p = 0; p < kTemporalParamCount; ++p)
      n.push_back(std::string("wet.") + temporal_param_name(p));
    for (int p = 0; p < kTemporalParamCount; ++p)
      n.push_back(std::string("dry.") + temporal_param_name(p));
    for (const char* c : {"confidence", "residual", "steps_used", "flags"}) n.push_back(c);
    return n;
  }();
  return names;
}

std::string TemporalFitOptions::validate() const {
  if (std::string e = brdf.validate(); !e.empty()) return "brdf: " + e;
  if (!(max_rate_times_interval > 0 && std::isfinite(max_rate_times_interval))) {
    return "max_rate_times_interval: expected > 0";
  }
  if (max_iterations < 1) return "max_iterations: expected >= 1";
  return {};
}

std::string TemporalSummary::to_string() const {
  std::ostringstream s;
  s << fitted << " of " << pixels << " pixels fitted, " << flagged << " flagged; models:";
  for (int m = 1; m < kTemporalModelCount; ++m) {
    s << ' ' << relight::to_string(TemporalModel(m)) << '=' << per_model[m];
  }
  s << "; flags: faster-than-sampling=" << faster_than_sampling
    << " too-few-steps=" << too_few_steps << " step-dropped=" << step_dropped
    << "; per-step BRDF fits " << seconds_steps << " s, temporal fits " << seconds_temporal << " s";
  return s.str();
}

double temporal_value(TemporalModel model, double rate, double onset, double wet, double dry,
                      double t) {
  const double s = shape_weight(model, rate, onset, t);
  return dry + (wet - dry) * s;
}

NormalMap estimate_temporal_normals(const std::vector<capture::ReflectanceField>& steps,
                                    const NormalOptions& options, NormalSource source) {
  check_same_layout(steps);
  std::vector<const capture::ReflectanceField*> sorted;
  for (const auto& f : steps) sorted.push_back(&f);
  return normals_from(sorted, options, source);
}

StepFit fit_step(const capture::ReflectanceField& field, const NormalMap& normals,
                 const TemporalFitOptions& options) {
  const int width = field.width(), height = field.height();
  StepFit out;
  out.time_s = field.scene_time_s;
  out.value = Image(width, height, kTemporalParamCount);
  out.sigma = Image(width, height, kTemporalParamCount);
  const capture::ValidLights valid = capture::valid_lights(field);
  out.valid_lights = int(valid.index.size());
  const NormalOptions& no = options.brdf.normals;
  const FitOptions& fo = options.brdf;
  if (!fo.view_dir_per_pixel.empty() && fo.view_dir_per_pixel.size() != size_t(width) * height) {
    throw InputError("temporal fit options: view_dir_per_pixel: expected " +
                     std::to_string(size_t(width) * height) + " directions, got " +
                     std::to_string(fo.view_dir_per_pixel.size()));
  }
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    std::vector<Sample> samples(valid.index.size());
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        if (int(normals.flags.at(x, y, 0)) != 0) continue;  // sigma 0: unusable.
        const float* px = field.pixel(x, y);
        double y_max = 0;
        for (const int l : valid.index) {
          const float* v = px + 3 * l;
          y_max = std::max(y_max, kLuma[0] * v[0] + kLuma[1] * v[1] + kLuma[2] * v[2]);
        }
        const double threshold =
            std::max(no.shadow_sigmas * std::sqrt(no.noise.a), no.shadow_fraction * y_max);
        int count = 0;
        for (size_t i = 0; i < valid.index.size(); ++i) {
          const float* v = px + 3 * valid.index[i];
          if (capture::is_saturated(field.lights()[valid.index[i]], v)) continue;
          const double lum = kLuma[0] * v[0] + kLuma[1] * v[1] + kLuma[2] * v[2];
          if (!(lum > threshold) || !std::isfinite(lum)) continue;
          Sample& s = samples[count++];
          s.l = capture::light_dir_at(field, valid.index[i], x, y);  // Per pixel for near LEDs.
          for (int c = 0; c < 3; ++c) {
            s.v[c] = v[c];
            s.inv_sigma[c] = 1 / std::sqrt(no.noise.variance(v[c]));
          }
        }
        // A lobe and Oren-Nayar need more than the normal's minimum: 6 parameters.
        if (count < std::max(no.min_lights, 7)) continue;
        StepPixel d;
        d.samples = samples.data();
        d.count = count;
        d.n = Eigen::Vector3d(normals.normal.at(x, y, 0), normals.normal.at(x, y, 1),
                              normals.normal.at(x, y, 2))
                  .normalized();
        d.wo = fo.view_dir_per_pixel.empty()
                   ? Eigen::Vector3d(0, 0, 1)
                   : fo.view_dir_per_pixel[size_t(y) * width + x].normalized();
        std::array<double, 6> start{};
        for (int c = 0; c < 3; ++c) {
          double sxx = 0, sxy = 0;
          for (int i = 0; i < count; ++i) {
            const double shade = std::max(0.0, d.n.dot(samples[i].l)) / kPi;
            const double w = samples[i].inv_sigma[c] * samples[i].inv_sigma[c];
            sxx += w * shade * shade;
            sxy += w * shade * samples[i].v[c];
          }
          start[c] = std::max(sxx > 0 ? sxy / sxx : 0.0, 1e-4);
        }
        start[kParamSigma] = 0.42;  // 24 degrees, as fit.cc starts Oren-Nayar.
        // The nested per-step models (Lambert, Oren-Nayar, each with or without the lobe), the
        // lowest BIC kept: a parameter the data do not support is fixed (sigma = 0, k_s = 0)
        // rather than left free to trade off against the albedo.
        std::array<StepResult, 4> fits;
        fits[0] = solve_step<false, false>(d, start, fo.max_iterations);
        if (fits[0].ok) std::copy(fits[0].q.begin(), fits[0].q.begin() + 3, start.begin());
        if (fo.fit_oren_nayar) {
          std::array<double, 6> s = start;
          for (int c = 0; c < 3; ++c) s[c] *= 1.07;  // A(sigma) ~ 0.87 at the start sigma.
          fits[1] = solve_step<true, false>(d, s, fo.max_iterations);
        }
        if (fo.fit_torrance_sparrow) {
          for (const double m0 : fo.roughness_starts) {
            std::array<double, 6> s = start;
            s[kParamKs] = 0.05;
            s[kParamRoughness] = m0;
            const StepResult lambert_lobe = solve_step<false, true>(d, s, fo.max_iterations);
            if (lambert_lobe.ok && lambert_lobe.q[kParamKs] <= fo.max_specular_albedo &&
                lambert_lobe.chi2 < fits[2].chi2) {
              fits[2] = lambert_lobe;
            }
          }
          // Oren-Nayar + lobe once, from the better lobe fit (a second start doubles the cost
          // for no measured gain).
          if (fo.fit_oren_nayar && fits[2].ok) {
            std::array<double, 6> s = fits[2].q;
            for (int c = 0; c < 3; ++c) s[c] *= 1.07;
            s[kParamSigma] = 0.42;
            const StepResult full = solve_step<true, true>(d, s, fo.max_iterations);
            if (full.ok && full.q[kParamKs] <= fo.max_specular_albedo) fits[3] = full;
          }
        }
        const double log_n = std::log(3.0 * count);
        int chosen = -1;
        for (int m = 0; m < 4; ++m) {
          if (!fits[m].ok) continue;
          if (chosen < 0 ||
              fits[m].chi2 + fits[m].k * log_n < fits[chosen].chi2 + fits[chosen].k * log_n) {
            chosen = m;
          }
        }
        if (chosen < 0) continue;
        const StepResult& best = fits[chosen];
        const std::array<double, 6> sig = step_sigmas(d, best);
        for (int p = 0; p < kTemporalParamCount; ++p) {
          out.value.at(x, y, p) = float(best.q[p]);
          out.sigma.at(x, y, p) = float(sig[p]);
        }
      }
    }
  });
  return out;
}

TemporalMaps fit_temporal_models(const std::vector<StepFit>& steps, const NormalMap& normals,
                                 const TemporalFitOptions& options) {
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError("temporal fit options: " + error);
  }
  if (steps.empty()) throw InputError("temporal fit: expected at least one time step, got none");
  if (steps.size() > size_t(kMaxSteps)) {
    throw InputError("temporal fit: expected at most " + std::to_string(kMaxSteps) +
                     " time steps, got " + std::to_string(steps.size()));
  }
  const auto start_time = std::chrono::steady_clock::now();
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
  TemporalSummary& summary = out.summary;
  summary.pixels = width * height;
  std::mutex mutex;
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
        series.steps = 0;
        for (const StepFit& s : steps) {
          if (!(s.sigma.at(x, y, 0) > 0)) {
            flags |= kStepDropped;
            continue;
          }
          const int i = series.steps++;
          series.t[i] = s.time_s;
          for (int p = 0; p < kTemporalParamCount; ++p) {
            double v = s.value.at(x, y, p), sd = s.sigma.at(x, y, p);
            if (p == kParamRoughness) {  // Fitted as 1/m: sigma(1/m) = sigma(m) / m^2.
              sd = sd / (v * v);
              v = 1 / v;
            }
            series.y[i][p] = v;
            series.w[i][p] = sd < kNoInformationSigma ? 1 / sd : 0.0;
          }
        }
        if (series.steps == 0) {
          m[kTFlags] = float(flags | kTemporalFitFailed);
          ++local.flagged;
          continue;
        }
        std::array<TemporalResult, kTemporalModelCount> fits;
        fits[1] = fit_constant(series);
        // A model needs more usable steps than its parameters per series (4: wet, dry, rate,
        // onset).
        const bool enough = series.steps >= 5;
        const bool wants_process =
            options.fit_exponential || options.fit_sigmoid || options.fit_dust;
        if (!enough && wants_process) flags |= kTooFewSteps;
        if (enough && options.fit_exponential) {
          fits[2] =
              fit_process<TemporalModel::kExponential>(series, bounds, options.max_iterations);
        }
        if (enough && options.fit_sigmoid) {
          fits[3] = fit_process<TemporalModel::kSigmoid>(series, bounds, options.max_iterations);
        }
        if (enough && options.fit_dust) {
          fits[4] = fit_process<TemporalModel::kDust>(series, bounds, options.max_iterations);
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
          continue;
        }
        const TemporalResult& f = fits[best];
        double weight_sum = 0;
        for (int k = 1; k < kTemporalModelCount; ++k) {
          if (std::isfinite(bic[k])) weight_sum += std::exp(-0.5 * (bic[k] - bic[best]));
        }
        const TemporalModel model = TemporalModel(best);
        if (model != TemporalModel::kConstant) {
          // Faster than sampling: 90% or more of the change falls between two consecutive
          // steps (or the rate sits at its bound): the curve there is a step whose rate and
          // onset the data only bound.
          double max_jump = 0;
          for (size_t i = 1; i < out.step_times_s.size(); ++i) {
            max_jump = std::max(
                max_jump, std::abs(shape_weight(model, f.rate, f.onset, out.step_times_s[i]) -
                                   shape_weight(model, f.rate, f.onset, out.step_times_s[i - 1])));
          }
          if (max_jump >= 0.9 || std::log(f.rate) >= bounds.log_rate_hi - 0.05) {
            flags |= kFasterThanSampling;
          }
          if (f.onset <= t_first + 1e-6 * std::max(span, 1.0) && model != TemporalModel::kSigmoid) {
            flags |= kOnsetAtCaptureStart;
          }
        }
        m[kTModel] = float(best);
        m[kTRate] = model == TemporalModel::kConstant ? 0.0f : float(f.rate);
        m[kTOnset] = model == TemporalModel::kConstant ? float(t_first) : float(f.onset);
        for (int p = 0; p < kTemporalParamCount; ++p) {
          m[kTWet + p] = float(clamp_param(p, to_physical(p, f.wet[p])));
          m[kTDry + p] = float(clamp_param(p, to_physical(p, f.dry[p])));
        }
        m[kTConfidence] = float(1 / weight_sum);
        const double dof = n - f.k;
        m[kTResidual] = float(dof > 0 ? f.chi2 / dof : f.chi2);
        m[kTStepsUsed] = float(series.steps);
        m[kTFlags] = float(flags);
        ++local.fitted;
        ++local.per_model[best];
        if (flags & kFasterThanSampling) ++local.faster_than_sampling;
        if (flags & kTooFewSteps) ++local.too_few_steps;
        if (flags & kStepDropped) ++local.step_dropped;
      }
      const long done = ++rows_done;
      if (options.progress) options.progress(done, height);
    }
    const std::lock_guard lock(mutex);
    summary.fitted += local.fitted;
    summary.flagged += local.flagged;
    summary.faster_than_sampling += local.faster_than_sampling;
    summary.too_few_steps += local.too_few_steps;
    summary.step_dropped += local.step_dropped;
    for (int k = 0; k < kTemporalModelCount; ++k) summary.per_model[k] += local.per_model[k];
  });
  summary.seconds_temporal =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  return out;
}

TemporalMaps fit_temporal(const std::vector<capture::ReflectanceField>& input,
                          const TemporalFitOptions& options) {
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError("temporal fit options: " + error);
  }
  check_same_layout(input);
  std::vector<const capture::ReflectanceField*> order;
  for (const auto& f : input) order.push_back(&f);
  std::stable_sort(order.begin(), order.end(),
                   [](auto* a, auto* b) { return a->scene_time_s < b->scene_time_s; });
  for (size_t i = 1; i < order.size(); ++i) {
    if (order[i]->scene_time_s == order[i - 1]->scene_time_s) {
      throw InputError(order[i]->source + ": scene_time_s: expected a time different from " +
                       order[i - 1]->source + "'s, got both " +
                       std::to_string(order[i]->scene_time_s) + " s");
    }
  }
  const auto start_time = std::chrono::steady_clock::now();
  const NormalMap normals = normals_from(order, options.brdf.normals, options.normal_source);
  const long total_rows = long(order.size() + 1) * input[0].height();
  std::atomic<long> done_rows{0};
  std::vector<StepFit> steps;
  for (auto* f : order) {
    steps.push_back(fit_step(*f, normals, options));
    done_rows += f->height();
    if (options.progress) options.progress(done_rows, total_rows);
  }
  const double seconds_steps =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  TemporalFitOptions temporal = options;
  const long base = done_rows;
  if (options.progress) {
    temporal.progress = [&, base](long done, long) { options.progress(base + done, total_rows); };
  }
  TemporalMaps out = fit_temporal_models(steps, normals, temporal);
  out.summary.seconds_steps = seconds_steps;
  return out;
}

void write_temporal_maps(const std::filesystem::path& path, const TemporalMaps& maps) {
  const Image& image = maps.maps;
  LS_CHECK(image.channels == kTemporalChannelCount &&
               image.pixels.size() == image.num_pixels() * kTemporalChannelCount,
           "temporal maps have " + std::to_string(image.channels) + " channels");
  const nlohmann::json meta = {{"step_times_s", maps.step_times_s},
                               {"read_variance", maps.noise.a},
                               {"shot_variance_per_unit", maps.noise.b},
                               {"noise_source", maps.noise_source}};
  Image named = image;
  named.channel_names = temporal_channel_names();
  write_exr(path, named, ExrPixelType::kFloat, {{kTemporalAttribute, meta.dump()}});
  const double span = std::max(maps.last_time_s() - maps.first_time_s(), 1e-9);
  double max_rate = 0;
  for (size_t i = 0; i < image.num_pixels(); ++i) {
    max_rate = std::max(max_rate, double(image.pixels[i * image.channels + kTRate]));
  }
  auto preview = [&](const std::string& name, int first, int channels, auto transform) {
    Image p(image.width, image.height, channels);
    for (size_t i = 0; i < image.num_pixels(); ++i) {
      for (int c = 0; c < channels; ++c) {
        const float v = image.pixels[i * image.channels + first + c];
        p.pixels[i * channels + c] = std::isfinite(v) ? float(transform(v)) : 0.0f;
      }
    }
    std::filesystem::path file = path;
    file.replace_extension(name + ".png");
    write_png_preview(file, p);
  };
  auto identity = [](float v) { return v; };
  preview("model", kTModel, 1, [](float v) { return v / 4; });
  preview("rate", kTRate, 1, [&](float v) { return max_rate > 0 ? v / max_rate : 0.0; });
  preview("onset", kTOnset, 1, [&](float v) { return (v - maps.first_time_s()) / span; });
  preview("wet_albedo", kTWet, 3, identity);
  preview("dry_albedo", kTDry, 3, identity);
  preview("wet_ks", kTWet + int(kParamKs), 1, identity);
  preview("dry_ks", kTDry + int(kParamKs), 1, identity);
  preview("confidence", kTConfidence, 1, identity);
  preview("flags", kTFlags, 1, [](float v) { return v / 127; });
}

TemporalMaps read_temporal_maps(const std::filesystem::path& path) {
  const std::string name = path.string();
  if (!std::filesystem::exists(path)) throw InputError(name + ": file not found");
  auto in = OIIO::ImageInput::open(name);
  if (!in) throw InputError(name + ": cannot read temporal maps: " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  const std::vector<std::string>& names = temporal_channel_names();
  std::vector<int> file_channel(kTemporalChannelCount, -1);
  for (int c = 0; c < kTemporalChannelCount; ++c) {
    for (int f = 0; f < spec.nchannels; ++f) {
      if (spec.channelnames[f] == names[c]) file_channel[c] = f;
    }
    if (file_channel[c] < 0) {
      throw InputError(name + ": channel '" + names[c] +
                       "': missing (not temporal maps from 'lightstage fit --time'?)");
    }
  }
  if (spec.width <= 0 || spec.height <= 0) throw InputError(name + ": image has no pixels");
  Image raw(spec.width, spec.height, spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, raw.pixels.data())) {
    throw InputError(name + ": cannot read pixels (truncated or corrupt file?): " + in->geterror());
  }
  TemporalMaps out;
  const OIIO::ParamValue* meta = spec.find_attribute(kTemporalAttribute);
  if (!meta) {
    throw InputError(name + ": attribute '" + kTemporalAttribute + "': missing (step times)");
  }
  try {
    const nlohmann::json j = nlohmann::json::parse(meta->get_string());
    out.step_times_s = j.at("step_times_s").get<std::vector<double>>();
    out.noise.a = j.at("read_variance").get<double>();
    out.noise.b = j.at("shot_variance_per_unit").get<double>();
    out.noise_source = j.value("noise_source", std::string());
  } catch (const nlohmann::json::exception& e) {
    throw InputError(
        name + ": attribute '" + kTemporalAttribute +
        "': expected {step_times_s, read_variance, shot_variance_per_unit}: " + e.what());
  }
  if (out.step_times_s.empty() ||
      !std::is_sorted(out.step_times_s.begin(), out.step_times_s.end())) {
    throw InputError(name + ": attribute '" + kTemporalAttribute +
                     "': step_times_s: expected a non-empty increasing list");
  }
  in->close();
  out.maps = Image(spec.width, spec.height, kTemporalChannelCount);
  out.maps.channel_names = names;
  for (size_t i = 0; i < raw.num_pixels(); ++i) {
    for (int c = 0; c < kTemporalChannelCount; ++c) {
      out.maps.pixels[i * kTemporalChannelCount + c] =
          raw.pixels[i * spec.nchannels + file_channel[c]];
    }
  }
  TemporalSummary& summary = out.summary;
  summary.pixels = spec.width * spec.height;
  for (int y = 0; y < spec.height; ++y) {
    for (int x = 0; x < spec.width; ++x) {
      for (int c = 0; c < kTemporalChannelCount; ++c) {
        const float v = out.maps.at(x, y, c);
        if (!std::isfinite(v)) {
          throw InputError(name + ": channel '" + names[c] + "': expected a finite value at (" +
                           std::to_string(x) + ", " + std::to_string(y) + ")");
        }
      }
      const float model = out.maps.at(x, y, kTModel);
      if (!(model == std::floor(model) && model >= 0 && model < kTemporalModelCount)) {
        throw InputError(name + ": channel 'model': expected an integer in 0..4 at (" +
                         std::to_string(x) + ", " + std::to_string(y) + "), got " +
                         std::to_string(model));
      }
      const float flags = out.maps.at(x, y, kTFlags);
      if (!(flags == std::floor(flags) && flags >= 0)) {
        throw InputError(name + ": channel 'flags': expected a non-negative integer at (" +
                         std::to_string(x) + ", " + std::to_string(y) + ")");
      }
      if (model == 0) {
        ++summary.flagged;
      } else {
        ++summary.fitted;
        ++summary.per_model[int(model)];
      }
    }
  }
  return out;
}

}  // namespace ls::relight
