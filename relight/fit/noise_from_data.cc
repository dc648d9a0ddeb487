#include "relight/fit/noise_from_data.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <utility>
#include <vector>

namespace ls::relight {

namespace {

constexpr int kBins = 12;
constexpr long kMinSamples = 2000;
constexpr double kMaxSamples = 4e5;
constexpr int kMinPixels = 100;

double robust_variance(std::vector<double>& residuals) {
  const auto median_of = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double median = median_of(residuals);
  for (double& r : residuals) r = std::abs(r - median);
  const double sigma = 1.4826 * median_of(residuals);
  return sigma * sigma;
}

// The data's own quantisation step near black: each light's smallest positive value (one code
// step at black for quantised data: 8-bit sRGB, 1/255/12.92 of that light's white), the median over
// the lights, so that a stray tiny value does not set it. Rounding to it has variance step^2 / 12.
double code_step(const capture::ReflectanceField& field) {
  std::vector<double> smallest;
  for (int l = 0; l < field.num_lights(); ++l) {
    float step = std::numeric_limits<float>::infinity();
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        const float* rgb = field.pixel(x, y) + 3 * size_t(l);
        for (int c = 0; c < 3; ++c) {
          if (rgb[c] > 0 && rgb[c] < step) step = rgb[c];
        }
      }
    }
    if (std::isfinite(step)) smallest.push_back(step);
  }
  if (smallest.empty()) return 0.0;
  std::nth_element(smallest.begin(), smallest.begin() + long(smallest.size() / 2), smallest.end());
  return smallest[smallest.size() / 2];
}

// One estimate, from the residuals of the normals solved with options.noise; `step`: code_step.
std::optional<DataNoise> noise_from_residuals(const capture::ReflectanceField& field,
                                              const NormalOptions& options, double step) {
  const capture::ValidLights valid = capture::valid_lights(field);
  // At most ~400k residuals (their memory, not their precision, is the limit): every k-th pixel,
  // the only ones whose normals are solved.
  const double all = 3.0 * double(valid.index.size()) * field.width() * field.height();
  const long stride = std::max(1L, long(std::ceil(all / kMaxSamples)));
  const NormalMap normals = estimate_normals(field, options, stride);
  // (predicted value, residual) over every usable sample, each scaled for its pixel's fit.
  std::vector<std::pair<double, double>> residuals;
  struct PixelResiduals {
    size_t first, end;  // Its range of `residuals`.
    double spread;      // Robust spread of its residuals over the noise assumed (1: as assumed).
  };
  std::vector<PixelResiduals> pixels;
  DataNoise out;
  for (long p = 0; p < long(field.width()) * field.height(); p += stride) {
    const int x = int(p % field.width()), y = int(p / field.width());
    if (int(normals.flags.at(x, y, 0)) != 0) continue;
    const Eigen::Vector3d n(normals.normal.at(x, y, 0), normals.normal.at(x, y, 1),
                            normals.normal.at(x, y, 2));
    const capture::PixelLightDirs pixel_dirs(field, x, y);
    const float* px = field.pixel(x, y);
    const size_t first = residuals.size();
    for (size_t i = 0; i < valid.index.size(); ++i) {
      const int l = valid.index[i];
      const double cos = n.dot(valid.near ? pixel_dirs(l) : valid.dirs_in_stage[i]);
      if (cos < 0.3) continue;  // Near the terminator Lambert is least true.
      const float* rgb = px + 3 * size_t(l);
      // Samples the normals left out stay out: censored (saturated) or not numbers.
      if (capture::is_saturated(field.lights()[size_t(l)], rgb)) continue;
      for (int c = 0; c < 3; ++c) {
        const double predicted = normals.albedo.at(x, y, c) * cos / std::numbers::pi;
        if (predicted > 0 && std::isfinite(rgb[c])) {
          residuals.emplace_back(predicted, rgb[c] - predicted);
        }
      }
    }
    const size_t used = (residuals.size() - first) / 3;  // Lights (channels pooled).
    if (used <= 3) {
      residuals.resize(first);
      continue;
    }
    const double dof = std::sqrt(double(used) / double(used - 3));
    std::vector<double> scaled;  // The residuals in units of the noise assumed so far.
    for (size_t k = first; k < residuals.size(); ++k) {
      residuals[k].second *= dof;
      scaled.push_back(residuals[k].second / std::sqrt(options.noise.variance(residuals[k].first)));
    }
    pixels.push_back({first, residuals.size(), std::sqrt(robust_variance(scaled))});
  }
  // Pixels the Lambertian model does not explain (a rough or glossy material, a penumbra across
  // the pixel) spread wider than the noise: those beyond 1.5 times the typical spread are left out.
  std::vector<double> spreads(pixels.size());
  std::transform(pixels.begin(), pixels.end(), spreads.begin(),
                 [](const PixelResiduals& p) { return p.spread; });
  if (spreads.empty()) return std::nullopt;
  std::nth_element(spreads.begin(), spreads.begin() + long(spreads.size() / 2), spreads.end());
  const double typical = spreads[spreads.size() / 2];
  size_t kept = 0;  // Compacted in place: the pixels kept, in order.
  for (const PixelResiduals& p : pixels) {
    if (p.spread > 1.5 * typical) continue;
    if (kept != p.first) {  // std::copy may not write into its own source range.
      std::copy(residuals.begin() + long(p.first), residuals.begin() + long(p.end),
                residuals.begin() + long(kept));
    }
    kept += p.end - p.first;
    ++out.pixels;
  }
  residuals.resize(kept);
  out.samples = long(residuals.size());
  if (out.samples < kMinSamples || out.pixels < kMinPixels) return std::nullopt;
  // Bins of equal counts along the predicted value.
  std::sort(residuals.begin(), residuals.end());
  Eigen::MatrixXd A(kBins, 2);
  Eigen::VectorXd b(kBins);
  const size_t per_bin = residuals.size() / kBins;
  for (int k = 0; k < kBins; ++k) {
    std::vector<double> bin;
    double level = 0;
    for (size_t i = size_t(k) * per_bin; i < size_t(k + 1) * per_bin; ++i) {
      bin.push_back(residuals[i].second);
      level += residuals[i].first;
    }
    level /= double(bin.size());
    const double variance = robust_variance(bin);
    // Weighted by the precision of a variance estimate (its spread grows with the variance).
    const double w = std::sqrt(double(bin.size())) / std::max(variance, 1e-30);
    A(k, 0) = w;
    A(k, 1) = w * level;
    b(k) = w * variance;
  }
  Eigen::Vector2d ab = A.colPivHouseholderQr().solve(b);
  if (ab(0) < 0 || ab(1) < 0) {  // Refit with the negative term held at 0.
    const int keep = ab(0) < 0 ? 1 : 0;
    const double t = A.col(keep).dot(b) / A.col(keep).squaredNorm();
    ab.setZero();
    ab(keep) = std::max(0.0, t);
  }
  if (!(ab(0) + ab(1) > 0)) return std::nullopt;
  out.model.a = std::max({ab(0), step * step / 12, 1e-12});  // NoiseModel divides by it.
  out.model.b = ab(1);
  return out;
}

}  // namespace

std::string DataNoise::describe() const {
  std::ostringstream s;
  s << "estimated from the data (no dark frames): residuals of a robust Lambertian fit, " << samples
    << " samples of " << pixels << " pixels";
  return s.str();
}

std::optional<DataNoise> noise_from_data(const capture::ReflectanceField& field,
                                         const NormalOptions& options) {
  // The normals' shadow threshold and robust weights depend on the noise: estimate, then estimate
  // again with what was found, until it settles.
  NormalOptions refined = options;
  const double step = code_step(field);  // Once: it is the data's, not the fit's.
  std::optional<DataNoise> found;
  for (int round = 0; round < 4; ++round) {
    found = noise_from_residuals(field, refined, step);
    if (!found) return found;
    const auto relative = [](double x, double y) {
      return std::abs(x - y) / std::max({std::abs(x), std::abs(y), 1e-30});
    };
    const double change =
        relative(found->model.a, refined.noise.a) + relative(found->model.b, refined.noise.b);
    refined.noise = found->model;
    if (change < 0.02) break;
  }
  return found;
}

}  // namespace ls::relight
