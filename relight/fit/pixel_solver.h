#pragma once
// The per-pixel solver core shared by the static fit (relight/fit/fit.cc), the per-step BRDF fits
// and the temporal curve fits (relight/time/temporal_step_fit.cc, temporal_models.cc): gathering a
// pixel's usable samples, the closed-form Lambert start, the bounded parametrisations, the sample
// residuals, and one wrapper around ceres::TinySolver that reports how the solver stopped.
//
// Conventions as in relight/fit/fit.h: R = (albedo * f_diffuse + k_s * f_lobe) * max(0, n.l) per
// channel, f in 1/sr (physics/brdf.h), each residual divided by its noise sigma
// (NoiseModel, relight/fit/normals.h), chi^2 = sum of squared residuals.
//
// Internal to relight_fit and relight_time (their .cc files include it): it pulls in Ceres.
#include <ceres/tiny_solver.h>
#include <ceres/tiny_solver_autodiff_function.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "capture/field.h"
#include "physics/brdf.h"
#include "relight/fit/normals.h"

namespace ls::relight::pixel {

inline constexpr double kPi = physics::brdf::kPi;
inline constexpr double kMinRoughness = 0.02;  // Beckmann m in [0.02, 1].

// ---------------------------------------------------------------------------------------------
// Samples.

struct Sample {
  Eigen::Vector3d l;  // Unit, toward the LED.
  double v[3];        // Measured R per channel.
  double inv_sigma[3];
};

struct GatheredSamples {
  int count = 0;      // Usable samples written.
  int saturated = 0;  // Left out at their light's saturation ceiling.
};

// Pixel (x, y)'s usable samples, as estimate_normals picks them (relight/fit/normals.h): valid
// lights, not at their saturation ceiling (a lower bound, not a measurement), luminance above
// max(shadow_sigmas * sqrt(noise.a), shadow_fraction * brightest luminance) (below: almost always
// a cast shadow, which no model here has). `samples` holds room for valid.index.size().
// With `shadowed`, the directions of the lights left out as shadowed are written there too.
GatheredSamples gather_samples(const capture::ReflectanceField& field,
                               const capture::ValidLights& valid, const NormalOptions& options,
                               int x, int y, Sample* samples,
                               std::vector<Eigen::Vector3d>* shadowed = nullptr);

// The samples a first fit of pixel (x, y) says are dim, not shadowed: gather_samples' samples plus
// those below its shadow threshold whose luminance `predicted` (the first fit's, for unit
// irradiance from direction l) is below the threshold too, within kDimMarginSigmas of the noise
// floor, and within kDimAgreementSigmas of the sample's own: a dim reflectance measured, not a
// cast shadow (which the fit, having no shadows, predicts bright) nor light the model does not
// explain. Leaving them out biases a dark pixel's fit bright (of its dim samples only those that
// noise lifted over the threshold are kept) and leaves a dark glossy pixel's normal to its
// highlight. Writes `samples` (room for valid.index.size()) in light order; returns their count,
// or 0 when none was readmitted (gather_samples' set stands).
inline constexpr double kDimMarginSigmas = 2;
inline constexpr double kDimAgreementSigmas = 2;
int gather_with_dim_samples(const capture::ReflectanceField& field,
                            const capture::ValidLights& valid, const NormalOptions& options, int x,
                            int y, const std::function<double(const Eigen::Vector3d& l)>& predicted,
                            Sample* samples);

// One pixel's fit problem: its usable samples, its photometric-stereo normal n0 with two tangents,
// and the view direction (unit, toward the camera).
struct PixelData {
  const Sample* samples = nullptr;
  int count = 0;
  Eigen::Vector3d n0, t1, t2, wo;
  bool refine_normal = true;  // Off: the two normal angles stay 0 (zero Jacobian columns).
};

// The fitted normal: n0 tilted by two small angles (angles[0], angles[1]) along the tangents,
// renormalised; n0 itself without refine_normal.
template <class T>
physics::brdf::Vec3<T> refined_normal(const PixelData& d, const T* angles) {
  using std::sqrt;
  if (!d.refine_normal) return d.n0.cast<T>();
  const physics::brdf::Vec3<T> n =
      d.n0.cast<T>() + d.t1.cast<T>() * angles[0] + d.t2.cast<T>() * angles[1];
  return n / sqrt(n.dot(n));
}

// Weighted least-squares albedo per channel of R = albedo/pi * max(0, n.l), at least 1e-4 (a
// strictly positive start keeps the u^2 parametrisation's gradient non-zero).
Eigen::Vector3d lambert_albedo(const Sample* samples, int count, const Eigen::Vector3d& n);

// The normal map's normal at (x, y), renormalised; the view direction at pixel index i (unit,
// toward the camera; orthographic (0, 0, 1) when per_pixel is empty).
Eigen::Vector3d normal_at(const NormalMap& normals, int x, int y);
Eigen::Vector3d view_dir_at(const std::vector<Eigen::Vector3d>& per_pixel, size_t i);
// Empty, or a message naming view_dir_per_pixel when it is neither empty nor one per pixel.
std::string check_view_dirs(const std::vector<Eigen::Vector3d>& per_pixel, int width, int height);

// Residuals r[3 i + c] of every sample: ((albedo_c * diffuse(g) + specular(g)) * max(0, cos_i) -
// v_c) / sigma_c, g the sample's geometry for normal n and view wo; diffuse(g) is the factor
// multiplying the albedo, specular(g) the lobe with its k_s.
template <class T, class Diffuse, class Specular>
void sample_residuals(const Sample* samples, int count, const physics::brdf::Vec3<T>& n,
                      const physics::brdf::Vec3<T>& wo, const T* albedo, const Diffuse& diffuse,
                      const Specular& specular, T* r) {
  for (int i = 0; i < count; ++i) {
    const Sample& s = samples[i];
    const auto g = physics::brdf::Geometry<T>::from_world(n, s.l.cast<T>(), wo);
    const T f_diffuse = diffuse(g);
    const T f_specular = specular(g);
    const T cos_i = g.cos_i > T(0) ? g.cos_i : T(0);
    for (int c = 0; c < 3; ++c) {
      r[3 * i + c] = ((albedo[c] * f_diffuse + f_specular) * cos_i - T(s.v[c])) * T(s.inv_sigma[c]);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Bounded parametrisations: LM runs unbounded on u, the bounds are built into the map.

template <class T>
T sigmoid(const T& u) {
  using std::exp;
  return T(1) / (T(1) + exp(-u));
}
inline double logit(double p) { return std::log(p / (1 - p)); }
// Kept 1e-4 inside (0, 1): a start on a bound would sit where the sigmoid has no gradient.
inline double clamped_logit(double p) { return logit(std::clamp(p, 1e-4, 1 - 1e-4)); }

// v = u^2 >= 0; the inverse floors v (> 0: u = 0 has no gradient).
template <class T>
T non_negative(const T& u) {
  return u * u;
}
inline double non_negative_inverse(double v, double floor) { return std::sqrt(std::max(v, floor)); }

// v = lo + (hi - lo) sigmoid(u), in (lo, hi).
template <class T>
T bounded(const T& u, double lo, double hi) {
  return T(lo) + T(hi - lo) * sigmoid(u);
}
inline double bounded_inverse(double v, double lo, double hi) {
  return logit((v - lo) / (hi - lo));
}
inline double clamped_bounded_inverse(double v, double lo, double hi) {
  return clamped_logit((v - lo) / (hi - lo));
}

// ---------------------------------------------------------------------------------------------
// The solver.

// How a solve ended. kConverged: a TinySolver tolerance was met. kHitIterationLimit: stopped on
// max_iterations, the parameters are finite but not at a minimum. kFailed: non-finite parameters
// or chi^2 (the result is unusable).
enum class SolverStatus { kConverged, kHitIterationLimit, kFailed };

template <int K>
struct SolveResult {
  SolverStatus status = SolverStatus::kFailed;
  Eigen::Matrix<double, K, 1> x;
  double chi2 = std::numeric_limits<double>::infinity();
  bool usable() const { return status != SolverStatus::kFailed; }
};

// chi^2 of a cost functor (NumResiduals(), operator()(const T* x, T* r)) at x, evaluated rather
// than trusted from the solver.
template <class Cost>
double chi2_at(const Cost& cost, const double* x) {
  thread_local std::vector<double> residuals;
  residuals.resize(size_t(cost.NumResiduals()));
  cost(x, residuals.data());
  double chi2 = 0;
  for (const double r : residuals) chi2 += r * r;
  return chi2;
}

// TinySolver's default: it stops once an accepted step lowers chi^2 by less than this (absolute,
// in chi^2 units).
inline constexpr double kDefaultChi2Tolerance = 1e-6;

// Levenberg-Marquardt (ceres::TinySolver) on a TinySolver function (residuals and Jacobian) from
// start, at most max_iterations iterations; chi^2 re-evaluated by cost.
template <class Function, class Cost, int K>
SolveResult<K> solve_function(const Function& function, const Cost& cost,
                              const Eigen::Matrix<double, K, 1>& start, int max_iterations,
                              double chi2_tolerance = kDefaultChi2Tolerance) {
  ceres::TinySolver<Function> solver;
  solver.options.max_num_iterations = max_iterations;
  solver.options.function_tolerance = chi2_tolerance;
  SolveResult<K> out;
  out.x = start;
  const auto& summary = solver.Solve(function, &out.x);
  if (out.x.allFinite()) out.chi2 = chi2_at(cost, out.x.data());
  if (!std::isfinite(out.chi2)) {
    out.status = SolverStatus::kFailed;
  } else if (summary.status == ceres::TinySolver<Function>::HIT_MAX_ITERATIONS) {
    out.status = SolverStatus::kHitIterationLimit;
  } else {
    out.status = SolverStatus::kConverged;
  }
  return out;
}

// The same with the Jacobian by autodiff Jets of a cost functor.
template <class Cost, int K>
SolveResult<K> solve(const Cost& cost, const Eigen::Matrix<double, K, 1>& start, int max_iterations,
                     double chi2_tolerance = kDefaultChi2Tolerance) {
  using Function = ceres::TinySolverAutoDiffFunction<Cost, Eigen::Dynamic, K>;
  return solve_function(Function(cost), cost, start, max_iterations, chi2_tolerance);
}

}  // namespace ls::relight::pixel
