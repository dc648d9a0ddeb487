// Per-step BRDF fits with fixed normals (relight/time/temporal_fit.h, step 2).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "lightstage/errors.h"
#include "physics/brdf.h"
#include "relight/fit/pixel_solver.h"
#include "relight/fit/profiled_fit.h"
#include "relight/time/temporal_fit.h"
#include "relight/time/temporal_fit_internal.h"

namespace ls::relight {
namespace {

using pixel::Sample;
using pixel::SolverStatus;
using temporal_internal::kMaxSigma;
using temporal_internal::kMinRoughness;
using temporal_internal::kNoInformationSigma;

// ---------------------------------------------------------------------------------------------
// Per-step BRDF fit with a fixed normal: Oren-Nayar diffuse + white Torrance-Sparrow lobe.

struct StepPixel {
  const Sample* samples = nullptr;
  int count = 0;
  Eigen::Vector3d n, wo;
};

// Residuals of the physical parameters q = (albedo r, g, b, sigma, k_s, roughness).
template <class T>
void step_residuals(const StepPixel& d, const T* q, T* r) {
  const auto diffuse = [&](const physics::brdf::Geometry<T>& g) {
    return physics::brdf::oren_nayar(g, q[3]);
  };
  const auto specular = [&](const physics::brdf::Geometry<T>& g) {
    return q[4] * physics::brdf::torrance_sparrow(g, q[5]);
  };
  pixel::sample_residuals(d.samples, d.count, physics::brdf::Vec3<T>(d.n.cast<T>()),
                          physics::brdf::Vec3<T>(d.wo.cast<T>()), q, diffuse, specular, r);
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
    for (int c = 0; c < 3; ++c) q[c] = pixel::non_negative(u[c]);
    q[3] = T(0);
    q[4] = T(0);
    q[5] = T(0.3);
    int k = 3;
    if constexpr (kOrenNayar) q[3] = pixel::bounded(u[k++], 0.0, kMaxSigma);
    if constexpr (kLobe) {
      q[4] = pixel::non_negative(u[k]);
      q[5] = pixel::bounded(u[k + 1], kMinRoughness, 1.0);
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
  SolverStatus status = SolverStatus::kFailed;
  double chi2 = std::numeric_limits<double>::infinity();
  std::array<double, 6> q{};
  std::array<bool, 6> used{};  // Parameters the model fitted (the others are fixed).
  int k = 0;
};

template <bool kOrenNayar, bool kLobe>
StepResult solve_step(const StepPixel& d, const std::array<double, 6>& start, int iterations) {
  using Cost = StepCostRaw<kOrenNayar, kLobe>;
  constexpr int K = Cost::kParams;
  Eigen::Matrix<double, K, 1> u;
  for (int c = 0; c < 3; ++c) u(c) = pixel::non_negative_inverse(start[c], 1e-6);
  int k = 3;
  if constexpr (kOrenNayar) {
    u(k++) = pixel::clamped_bounded_inverse(std::max(start[3], 0.05), 0.0, kMaxSigma);
  }
  if constexpr (kLobe) {
    u(k) = pixel::non_negative_inverse(start[4], 1e-6);
    u(k + 1) = pixel::clamped_bounded_inverse(start[5], kMinRoughness, 1.0);
  }
  const pixel::SolveResult<K> solved = pixel::solve(Cost{&d}, u, iterations);
  StepResult out;
  out.status = solved.status;
  out.k = K;
  out.used = {true, true, true, kOrenNayar, kLobe, kLobe};
  if (!solved.x.allFinite()) return out;
  Cost::physical(solved.x.data(), out.q.data());
  out.chi2 = solved.chi2;
  out.ok = solved.usable();
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
// rendered: the deviations of what a render sees (StepFit::rendered_sigma) by the same covariance,
// joint where the model fits both parts.
std::array<double, 6> step_sigmas(const StepPixel& d, const StepResult& fit,
                                  std::array<double, kRenderedCount>* rendered) {
  using Function = ceres::TinySolverAutoDiffFunction<StepCostPhysical, Eigen::Dynamic, 6>;
  const StepCostPhysical cost{&d};
  const Function function(cost);
  const int n = cost.NumResiduals();
  Eigen::VectorXd residuals(n);
  Eigen::MatrixXd jacobian(n, 6);
  std::array<double, 6> sigmas;
  sigmas.fill(kNoInformationSigma);
  rendered->fill(kNoInformationSigma);
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
  // The variance of g(q) for a gradient over two parameters (a, b): joint where the model fitted
  // both, else from the first one's own.
  const auto combined = [&](int a, int b, double ga, double gb) {
    double v = ga * ga * variance[a];
    if (fit.used[a] && fit.used[b]) {
      const auto at = [&](int p) {
        return int(std::find(used.begin(), used.end(), p) - used.begin());
      };
      const int i = at(a), j = at(b);
      v = ga * ga * covariance(i, i) + 2 * ga * gb * covariance(i, j) + gb * gb * covariance(j, j);
    }
    v *= scale;
    return std::isfinite(v) && v > 0 ? std::min(std::sqrt(v), kNoInformationSigma)
                                     : kNoInformationSigma;
  };
  // d(albedo A(sigma)) = A d albedo + albedo A'(sigma) d sigma.
  const double sigma = fit.q[kParamSigma];
  const double a = physics::brdf::oren_nayar_a(sigma),
               a_prime = physics::brdf::oren_nayar_a_slope(sigma);
  for (int c = 0; c < 3; ++c) {
    (*rendered)[size_t(c)] = combined(c, kParamSigma, a, fit.q[size_t(c)] * a_prime);
  }
  // d(k_s / m^2) = dk_s / m^2 - 2 k_s dm / m^3.
  const double m = fit.q[kParamRoughness], ks = fit.q[kParamKs];
  (*rendered)[kRenderedPeak] =
      combined(kParamKs, kParamRoughness, 1 / (m * m), -2 * ks / (m * m * m));
  return sigmas;
}

// The fit with the lowest BIC of those given (ok false: none).
StepResult lowest_bic(const std::array<StepResult, 4>& fits, int count) {
  const double log_n = std::log(3.0 * count);
  int chosen = -1;
  for (int m = 0; m < 4; ++m) {
    if (!fits[m].ok) continue;
    if (chosen < 0 ||
        fits[m].chi2 + fits[m].k * log_n < fits[chosen].chi2 + fits[chosen].k * log_n) {
      chosen = m;
    }
  }
  return chosen < 0 ? StepResult{} : fits[chosen];
}

// A closed-form candidate (relight/fit/profiled_fit.h) as a step fit.
StepResult step_result(const profiled::Candidate& c, bool oren_nayar, bool lobe) {
  StepResult out;
  if (!c.ok) return out;
  out.ok = true;
  out.status = SolverStatus::kConverged;
  out.chi2 = c.chi2;
  out.q = {c.albedo(0), c.albedo(1), c.albedo(2), c.sigma, c.ks, lobe ? c.roughness : 0.3};
  out.used = {true, true, true, oren_nayar, lobe, lobe};
  out.k = 3 + (oren_nayar ? 1 : 0) + (lobe ? 2 : 0);
  return out;
}

// Golden-section steps on log(roughness) after the closed-form grid: the step fits are not
// polished by LM, and the temporal series see the roughness to about 0.5% with these.
constexpr int kStepRoughnessRefineSteps = 8;

// The nested per-step models in closed form at the fixed normal (the default solver, as fit.cc's).
StepResult fit_step_pixel_profiled(const StepPixel& d, const FitOptions& fo) {
  thread_local profiled::PixelTerms terms;
  terms.reset(d.samples, d.count, d.n, d.wo);
  terms.search_unresolved_lobes();
  std::array<StepResult, 4> fits;
  fits[0] = step_result(terms.lambert(), false, false);
  if (fo.fit_oren_nayar) fits[1] = step_result(terms.oren_nayar(), true, false);
  if (fo.fit_torrance_sparrow) {
    const double max_ks = fo.max_specular_albedo;
    fits[2] = step_result(terms.torrance_sparrow(max_ks, kStepRoughnessRefineSteps), false, true);
    // Forward selection: both together only where either alone is worth its parameters over
    // Lambert (the search over both costs more than the other three together).
    const auto better_than_lambert = [&](const StepResult& f) {
      return f.ok && fits[0].ok &&
             f.chi2 + (f.k - fits[0].k) * std::log(3.0 * d.count) < fits[0].chi2;
    };
    if (fo.fit_oren_nayar && (better_than_lambert(fits[1]) || better_than_lambert(fits[2]))) {
      fits[3] = step_result(terms.oren_nayar_torrance_sparrow(max_ks, kStepRoughnessRefineSteps),
                            true, true);
    }
  }
  return lowest_bic(fits, d.count);
}

// The nested per-step models (Lambert, Oren-Nayar, each with or without the lobe), the lowest BIC
// kept: a parameter the data do not support is fixed (sigma = 0, k_s = 0) rather than left free to
// trade off against the albedo. Returns the kept fit (ok false: none).
StepResult fit_step_pixel(const StepPixel& d, const FitOptions& fo) {
  if (fo.solver == FitSolver::kProfiled) return fit_step_pixel_profiled(d, fo);
  std::array<double, 6> start{};
  const Eigen::Vector3d albedo = pixel::lambert_albedo(d.samples, d.count, d.n);
  for (int c = 0; c < 3; ++c) start[c] = albedo(c);
  start[kParamSigma] = 0.42;  // 24 degrees, as fit.cc starts Oren-Nayar.
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
    // Oren-Nayar + lobe once, from the better lobe fit (a second start doubles the cost for no
    // measured gain).
    if (fo.fit_oren_nayar && fits[2].ok) {
      std::array<double, 6> s = fits[2].q;
      for (int c = 0; c < 3; ++c) s[c] *= 1.07;
      s[kParamSigma] = 0.42;
      const StepResult full = solve_step<true, true>(d, s, fo.max_iterations);
      if (full.ok && full.q[kParamKs] <= fo.max_specular_albedo) fits[3] = full;
    }
  }
  return lowest_bic(fits, d.count);
}

// A step's fitted parameters q as the material they render: Oren-Nayar diffuse plus a white
// Torrance-Sparrow lobe (as step_residuals).
physics::brdf::Material step_material(const std::array<double, 6>& q) {
  physics::brdf::Material m;
  m.diffuse = physics::brdf::DiffuseModel::kOrenNayar;
  m.albedo = Eigen::Vector3d(q[kParamAlbedoR], q[kParamAlbedoG], q[kParamAlbedoB]);
  m.sigma_rad = q[kParamSigma];
  m.specular = physics::brdf::SpecularModel::kTorranceSparrow;
  m.ks = Eigen::Vector3d::Constant(q[kParamKs]);
  m.roughness = q[kParamRoughness];
  return m;
}

}  // namespace

StepFit fit_step(const capture::ReflectanceField& field, const NormalMap& normals,
                 const TemporalFitOptions& options) {
  const int width = field.width(), height = field.height();
  StepFit out;
  out.time_s = field.scene_time_s;
  out.value = Image(width, height, kTemporalParamCount);
  out.sigma = Image(width, height, kTemporalParamCount);
  out.flags = Image(width, height, 1);
  out.rendered_sigma = Image(width, height, kRenderedCount);
  const capture::ValidLights valid = capture::valid_lights(field);
  out.valid_lights = int(valid.index.size());
  const NormalOptions& no = options.brdf.normals;
  const FitOptions& fo = options.brdf;
  // view_dir_per_pixel covers the frame: a band (field.first_row()) looks its rows up there.
  if (const std::string error =
          pixel::check_view_dirs(fo.view_dir_per_pixel, width, field.frame_height());
      !error.empty()) {
    throw InputError("temporal fit options: " + error);
  }
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    std::vector<Sample> samples(valid.index.size());
    std::vector<Sample> dim(fo.readmit_dim_samples ? valid.index.size() : 0);
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        if (int(normals.flags.at(x, y, 0)) != 0) continue;  // sigma 0: unusable.
        const int count = pixel::gather_samples(field, valid, no, x, y, samples.data()).count;
        // A lobe and Oren-Nayar need more than the normal's minimum: 6 parameters.
        if (count < std::max(no.min_lights, 7)) continue;
        StepPixel d;
        d.samples = samples.data();
        d.count = count;
        d.n = pixel::normal_at(normals, x, y);
        d.wo = pixel::view_dir_at(fo.view_dir_per_pixel, size_t(field.first_row() + y) * width + x);
        StepResult best = fit_step_pixel(d, fo);
        if (!best.ok) continue;
        if (fo.readmit_dim_samples) {  // As fit_models does (relight/fit/fit.h).
          const physics::brdf::Material material = step_material(best.q);
          const auto predicted = [&](const Eigen::Vector3d& l) {
            const auto g = physics::brdf::Geometry<double>::from_world(d.n, l, d.wo);
            return g.cos_i > 0 ? luminance(physics::brdf::eval(material, g)) * g.cos_i : 0.0;
          };
          const int with_dim =
              pixel::gather_with_dim_samples(field, valid, no, x, y, predicted, dim.data());
          if (with_dim > 0) {
            StepPixel again = d;
            again.samples = dim.data();
            again.count = with_dim;
            const StepResult refit = fit_step_pixel(again, fo);
            if (refit.ok) best = refit, d = again;
          }
        }
        std::array<double, kRenderedCount> rendered{};
        const std::array<double, 6> sig = step_sigmas(d, best, &rendered);
        for (int r = 0; r < kRenderedCount; ++r) {
          out.rendered_sigma.at(x, y, r) = float(rendered[size_t(r)]);
        }
        for (int p = 0; p < kTemporalParamCount; ++p) {
          out.value.at(x, y, p) = float(best.q[p]);
          out.sigma.at(x, y, p) = float(sig[p]);
        }
        if (best.status != SolverStatus::kConverged) out.flags.at(x, y, 0) = kTemporalNotConverged;
      }
    }
  });
  return out;
}

namespace {

// One step's albedo and k_s of pixel (x, y) as a render sees them (RenderedParam) in y and their
// weights w (1 / sigma): the step's joint deviations where it has them, else propagated from the
// parameters' own (no covariance: wider), floored at the parameters' floors.
void to_rendered(const StepFit& s, int x, int y, double* value, double* weight) {
  const bool joint = !s.rendered_sigma.pixels.empty();
  const auto set = [&](int p, double v, double sd, double floor) {
    sd = std::max(sd, floor);
    value[p] = v;
    weight[p] = sd < kNoInformationSigma ? 1 / sd : 0.0;
  };
  const double sigma = s.value.at(x, y, kParamSigma), sd_sigma = s.sigma.at(x, y, kParamSigma);
  const double a = physics::brdf::oren_nayar_a(sigma),
               a_prime = physics::brdf::oren_nayar_a_slope(sigma);
  for (int c = 0; c < 3; ++c) {
    const double albedo = s.value.at(x, y, c), sd = s.sigma.at(x, y, c);
    const double propagated = std::hypot(a * sd, albedo * a_prime * sd_sigma);
    set(c, albedo * a, joint ? double(s.rendered_sigma.at(x, y, c)) : propagated,
        kParamSigmaFloor[c] * a);
  }
  const double ks = s.value.at(x, y, kParamKs), m = s.value.at(x, y, kParamRoughness);
  const double sd_ks = s.sigma.at(x, y, kParamKs), sd_m = s.sigma.at(x, y, kParamRoughness);
  const double propagated =
      std::hypot(sd_ks / (m * m), sd_m < kNoInformationSigma ? 2 * ks * sd_m / (m * m * m) : 0.0);
  set(kParamKs, ks / (m * m), joint ? double(s.rendered_sigma.at(x, y, kRenderedPeak)) : propagated,
      kParamSigmaFloor[kParamKs] / (m * m));
}

}  // namespace

int temporal_internal::gather_series(const std::vector<StepFit>& steps, int x, int y,
                                     Series& series, bool curves) {
  int flags = 0;
  series.steps = 0;
  for (const StepFit& s : steps) {
    if (!(s.sigma.at(x, y, 0) > 0)) {
      flags |= kStepDropped;
      continue;
    }
    if (!s.flags.pixels.empty()) flags |= int(s.flags.at(x, y, 0)) & kTemporalNotConverged;
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
    if (curves) to_rendered(s, x, y, series.y[i], series.w[i]);
  }
  for (int p = 0; p < kTemporalParamCount; ++p) {
    const temporal_internal::ParamRange r = temporal_internal::range_of(series, p);
    series.change_scale[p] =
        curves && r.informed() ? 2 * std::max(r.hi - r.lo, 3 * r.smallest_sigma) : 0.0;
  }
  return flags;
}

}  // namespace ls::relight
