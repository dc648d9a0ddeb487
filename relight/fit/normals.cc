#include "relight/fit/normals.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/image.h"

namespace ls::relight {
namespace {

// IRLS stops once a pass moves g by less than this fraction of |g|: the normal by under 1e-4 rad
// (0.006 degrees, far below any normal's error), which most pixels reach in two or three passes.
constexpr double kIrlsTolerance = 1e-4;
// The predicted angular error at which a normal's confidence is 0.5 (store_solution).
constexpr double kConfidenceDegrees = 1.0;

// Per-thread scratch, sized once per row range: the per-pixel loop does not allocate.
struct Scratch {
  std::vector<double> y;                    // Luminance per valid light.
  std::vector<double> sigma;                // Noise sigma of y.
  std::vector<double> weight;               // Current LS weight (0 = not used).
  std::vector<double> kept_weight;          // IRLS: the previous pass's weights.
  std::vector<double> abs_u;                // |normalised residual|, for the MAD.
  std::vector<double> residual;             // y - l.g of the current solve (IRLS).
  std::vector<int> order;                   // For trimming.
  std::vector<char> usable;                 // Lit (above the shadow threshold) and not saturated.
  std::vector<Eigen::Vector3d> pixel_dirs;  // Near lights: this pixel's direction to each light.
  explicit Scratch(size_t n)
      : y(n),
        sigma(n),
        weight(n),
        kept_weight(n),
        abs_u(n),
        residual(n),
        order(n),
        usable(n),
        pixel_dirs(n) {}
};

struct Solve {
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  double condition = 0;  // sqrt(lambda_min / lambda_max) of the used directions' scatter.
  int used = 0;
  bool ok = false;
};

// Weighted LS for g over the lights with weight > 0; the condition is left for the caller
// (condition_of), which needs it once per pixel, not once per IRLS pass.
Solve weighted_solve(const std::vector<Eigen::Vector3d>& dirs, const Scratch& s) {
  double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;  // Lower triangle of L^T W L.
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  Solve out;
  for (size_t i = 0; i < dirs.size(); ++i) {
    const double w = s.weight[i];
    if (!(w > 0)) continue;
    const Eigen::Vector3d& l = dirs[i];
    const double wx = w * l.x(), wy = w * l.y(), wz = w * l.z();
    xx += wx * l.x(), xy += wy * l.x(), xz += wz * l.x();
    yy += wy * l.y(), yz += wz * l.y(), zz += wz * l.z();
    atb += (w * s.y[i]) * l;
    ++out.used;
  }
  if (out.used < 3) return out;
  Eigen::Matrix3d ata;
  ata << xx, xy, xz, xy, yy, yz, xz, yz, zz;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
  if (ldlt.info() != Eigen::Success) return out;
  out.g = ldlt.solve(atb);
  out.ok = out.g.allFinite();
  return out;
}

// sqrt(lambda_min / lambda_max) of the scatter of the used directions (weight > 0), unweighted:
// how well their geometry alone pins down three unknowns.
double condition_of(const std::vector<Eigen::Vector3d>& dirs, const Scratch& s) {
  Eigen::Matrix3d geometry = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < dirs.size(); ++i) {
    if (s.weight[i] > 0) geometry.noalias() += dirs[i] * dirs[i].transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(geometry, Eigen::EigenvaluesOnly);  // Closed form for 3x3.
  const Eigen::Vector3d ev = eig.eigenvalues();         // Ascending.
  return ev(2) > 0 ? std::sqrt(std::max(ev(0), 0.0) / ev(2)) : 0.0;
}

double median_of(std::vector<double>& v, int n) {
  auto mid = v.begin() + n / 2;
  std::nth_element(v.begin(), mid, v.begin() + n);
  return *mid;
}

}  // namespace

std::string NormalOptions::validate() const {
  if (!(noise.a > 0) || !(noise.b >= 0)) {
    return "noise: expected a > 0 and b >= 0 (sigma^2 = a + b * value)";
  }
  if (!(shadow_sigmas >= 0) || !(shadow_fraction >= 0 && shadow_fraction < 1)) {
    return "shadow_sigmas must be >= 0 and shadow_fraction in [0, 1)";
  }
  if (min_lights < 3) return "min_lights: expected at least 3 (three unknowns per pixel)";
  if (!(min_condition >= 0 && min_condition < 1)) return "min_condition: expected [0, 1)";
  if (!(trim_bright_fraction >= 0 && trim_bright_fraction < 0.5)) {
    return "trim_bright_fraction: expected [0, 0.5)";
  }
  if (irls_iterations < 0) return "irls_iterations: expected >= 0";
  if (!(max_saturated_fraction >= 0 && max_saturated_fraction <= 1)) {
    return "max_saturated_fraction: expected [0, 1]";
  }
  if (!(tukey_c > 0)) return "tukey_c: expected > 0";
  return {};
}

namespace {

// Loads the pixel's luminance samples and their noise, leaves out shadowed and clipped ones, and
// returns the flags that rule the pixel out before any solve (0: solve it).
int gather_samples(const float* px, const std::vector<capture::FieldLight>& lights,
                   const std::vector<int>& light_index, const NormalOptions& options, Scratch& s) {
  const size_t n = light_index.size();
  double y_max = 0;
  for (size_t i = 0; i < n; ++i) {
    const float* v = px + 3 * size_t(light_index[i]);
    const double lum = luminance(v[0], v[1], v[2]);
    s.y[i] = std::isfinite(lum) ? lum : 0.0;
    s.sigma[i] = std::sqrt(options.noise.variance(s.y[i]));
    y_max = std::max(y_max, s.y[i]);
  }
  const double threshold =
      std::max(options.shadow_sigmas * std::sqrt(options.noise.a), options.shadow_fraction * y_max);
  int lit = 0;
  int saturated = 0;
  for (size_t i = 0; i < n; ++i) {
    const bool censored =
        capture::is_saturated(lights[light_index[i]], px + 3 * size_t(light_index[i]));
    const bool use = s.y[i] > threshold && !censored;
    s.usable[i] = use;
    s.weight[i] = use ? 1.0 / (s.sigma[i] * s.sigma[i]) : 0.0;
    lit += use;
    saturated += censored;
  }
  int flags = 0;
  if (lit == 0 && saturated == 0) {
    flags |= kAllShadowed;
  } else if (lit < options.min_lights) {
    flags |= kTooFewLights;
    if (saturated > 0) flags |= kSaturated;
  } else if (saturated > options.max_saturated_fraction * (lit + saturated)) {
    flags |= kSaturated;
  }
  return flags;
}

// Trimmed start (the brightest lit samples left out: highlights live there), then Tukey IRLS over
// all lit samples with residuals in noise units and the scale from their MAD.
Solve robust_solve(const std::vector<Eigen::Vector3d>& dirs, const NormalOptions& options,
                   Scratch& s) {
  const size_t n = dirs.size();
  Solve solve;
  int m = 0;
  for (size_t i = 0; i < n; ++i) {
    if (s.weight[i] > 0) s.order[m++] = int(i);
  }
  const int drop = int(options.trim_bright_fraction * m);
  if (m - drop >= options.min_lights && drop > 0) {
    std::nth_element(s.order.begin(), s.order.begin() + (m - drop), s.order.begin() + m,
                     [&](int a, int b) { return s.y[a] < s.y[b]; });
    std::copy(s.weight.begin(), s.weight.end(), s.abs_u.begin());  // Keep full weights.
    for (int k = m - drop; k < m; ++k) s.weight[s.order[k]] = 0;
    solve = weighted_solve(dirs, s);
    std::copy(s.abs_u.begin(), s.abs_u.end(), s.weight.begin());
  } else {
    solve = weighted_solve(dirs, s);
  }
  for (int it = 0; it < options.irls_iterations && solve.ok; ++it) {
    int k = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!s.usable[i]) continue;
      s.residual[i] = s.y[i] - dirs[i].dot(solve.g);
      s.abs_u[k++] = std::abs(s.residual[i]) / s.sigma[i];
    }
    const double scale = std::max(1.4826 * median_of(s.abs_u, k), 1.0);
    s.kept_weight.swap(s.weight);
    for (size_t i = 0; i < n; ++i) {
      if (!s.usable[i]) {
        s.weight[i] = 0;
        continue;
      }
      const double u = s.residual[i] / (s.sigma[i] * options.tukey_c * scale);
      const double t = 1 - u * u;
      s.weight[i] = t > 0 ? t * t / (s.sigma[i] * s.sigma[i]) : 0.0;
    }
    const Solve next = weighted_solve(dirs, s);
    if (!next.ok || next.used < options.min_lights) {
      s.weight.swap(s.kept_weight);  // The weights of the solve that is kept.
      break;
    }
    const double change = (next.g - solve.g).norm();
    solve = next;
    if (change <= kIrlsTolerance * solve.g.norm()) break;  // Converged: the weights are fixed.
  }
  return solve;
}

// The normal, the albedo per channel (weighted LS with the shading fixed) and the confidence of a
// solved pixel.
void store_solution(const Solve& solve, const std::vector<Eigen::Vector3d>& dirs,
                    const std::vector<int>& light_index, const float* px, const Scratch& s, int x,
                    int y, NormalMap& out) {
  const Eigen::Vector3d nrm = solve.g / solve.g.norm();
  double sxx = 0, sxy[3] = {0, 0, 0}, chi2 = 0;           // chi^2 of the luminance fit (weighted).
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();  // L^T W L.
  int used = 0;
  for (size_t i = 0; i < dirs.size(); ++i) {
    if (!(s.weight[i] > 0)) continue;
    const double shade = std::max(0.0, nrm.dot(dirs[i])) / std::numbers::pi;
    const double w = s.weight[i] * s.sigma[i] * s.sigma[i];  // Robust factor only.
    const float* v = px + 3 * size_t(light_index[i]);
    sxx += w * shade * shade;
    for (int c = 0; c < 3; ++c) sxy[c] += w * shade * v[c];
    const double r = s.y[i] - dirs[i].dot(solve.g);
    chi2 += s.weight[i] * r * r;
    information.noalias() += s.weight[i] * dirs[i] * dirs[i].transpose();
    ++used;
  }
  float* normal = &out.normal.at(x, y, 0);
  float* albedo = &out.albedo.at(x, y, 0);
  for (int c = 0; c < 3; ++c) {
    normal[c] = float(nrm(c));
    albedo[c] = sxx > 0 ? float(std::max(0.0, sxy[c] / sxx)) : 0.0f;
  }
  // Confidence: the normal's standard error from the fit, as an angle: the covariance of g is
  // s^2 (L^T W L)^-1 (s^2 the reduced chi^2, at least 1: residuals below the noise do not make a
  // normal surer than the noise does), its part across the normal over |g|. 1 / (1 + error / 1
  // degree): 0.5 at a predicted one degree; lower where the lights pin the normal down poorly or
  // the model explains them poorly.
  const double reduced_chi2 = used > 3 ? std::max(1.0, chi2 / (used - 3)) : 1.0;
  const Eigen::Matrix3d across = Eigen::Matrix3d::Identity() - nrm * nrm.transpose();
  const Eigen::Matrix3d covariance = reduced_chi2 * information.inverse();
  const double error_deg = std::sqrt(std::max(0.0, (across * covariance * across).trace())) /
                           solve.g.norm() * 180 / std::numbers::pi;
  out.confidence.at(x, y, 0) =
      std::isfinite(error_deg) ? float(1 / (1 + error_deg / kConfidenceDegrees)) : 0.0f;
}

}  // namespace

NormalMap estimate_normals(const capture::ReflectanceField& field, const NormalOptions& options,
                           long pixel_stride) {
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError("normal options: " + error);
  }
  LS_CHECK(pixel_stride >= 1, "pixel_stride " + std::to_string(pixel_stride) + " < 1");
  const int width = field.width(), height = field.height();
  NormalMap out;
  out.normal = Image(width, height, 3);
  out.normal.channel_names = {"normal.x", "normal.y", "normal.z"};
  out.albedo = Image(width, height, 3);
  out.albedo.channel_names = {"albedo.r", "albedo.g", "albedo.b"};
  out.confidence = Image(width, height, 1);
  out.confidence.channel_names = {"confidence"};
  out.flags = Image(width, height, 1);
  out.flags.channel_names = {"flags"};

  const capture::ValidLights valid = capture::valid_lights(field);
  const std::vector<int>& light_index = valid.index;
  const std::vector<Eigen::Vector3d>& distant_dirs = valid.dirs_in_stage;
  const size_t n = distant_dirs.size();
  // Near LEDs (positions in the field): each pixel sees them from its own reference point.
  const bool per_pixel_dirs = valid.near;
  const bool robust = options.method == NormalMethod::kRobust;
  std::atomic<int> flagged{0}, empty{0};

  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    Scratch s(n);
    int flagged_here = 0, empty_here = 0;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        if ((long(y) * width + x) % pixel_stride != 0) {
          out.flags.at(x, y, 0) = float(kNoSignal);
          continue;
        }
        const float* px = field.pixel(x, y);
        if (std::all_of(px, px + 3 * size_t(field.num_lights()), [](float v) { return v == 0; })) {
          out.flags.at(x, y, 0) = float(kNoSignal);
          ++empty_here;
          continue;
        }
        if (per_pixel_dirs) {
          const capture::PixelLightDirs dir_to(field, x, y);
          for (size_t i = 0; i < n; ++i) s.pixel_dirs[i] = dir_to(light_index[i]);
        }
        const std::vector<Eigen::Vector3d>& dirs = per_pixel_dirs ? s.pixel_dirs : distant_dirs;
        int flags = gather_samples(px, field.lights(), light_index, options, s);
        Solve solve;
        if (flags == 0) {
          solve = robust ? robust_solve(dirs, options, s) : weighted_solve(dirs, s);
          if (solve.ok) solve.condition = condition_of(dirs, s);
        }
        const double norm = solve.g.norm();
        if (flags == 0) {
          if (!solve.ok || solve.used < options.min_lights) {
            flags |= kTooFewLights;
          } else if (solve.condition < options.min_condition) {
            flags |= kIllConditioned;
          } else if (!(norm > 0) || solve.g.z() < -0.2 * norm) {
            flags |= kFacingAway;
          }
        }
        out.flags.at(x, y, 0) = float(flags);
        if (flags != 0) {
          ++flagged_here;
          continue;  // Maps stay zero: never NaN.
        }
        store_solution(solve, dirs, light_index, px, s, x, y, out);
      }
    }
    flagged += flagged_here;
    empty += empty_here;
  });
  out.flagged_pixels = flagged.load();
  out.empty_pixels = empty.load();
  return out;
}

}  // namespace ls::relight
