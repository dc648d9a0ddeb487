// Per-step BRDF fits with fixed normals (relight/time/temporal_fit.h, step 2).
#include <ceres/tiny_solver.h>
#include <ceres/tiny_solver_autodiff_function.h>
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
#include "relight/lighting/brdf.h"
#include "relight/time/temporal_fit.h"
#include "relight/time/temporal_fit_internal.h"

namespace ls::relight {
namespace {

using temporal_internal::kMaxSigma;
using temporal_internal::kMinRoughness;
using temporal_internal::kNoInformationSigma;
using temporal_internal::kPi;
using temporal_internal::logit;
using temporal_internal::sigmoid;

constexpr double kLuma[3] = {0.2126, 0.7152, 0.0722};

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

}  // namespace

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

}  // namespace ls::relight
