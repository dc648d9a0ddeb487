#include "relight/fit/pixel_solver.h"

#include <optional>
#include <string>

#include "lightstage/image.h"

namespace ls::relight::pixel {

namespace {

// gather_samples' threshold at the pixel: below it, a sample is taken as shadowed.
double shadow_threshold(const float* px, const capture::ValidLights& valid,
                        const NormalOptions& options) {
  double y_max = 0;
  for (const int l : valid.index) {
    const float* v = px + 3 * size_t(l);
    y_max = std::max(y_max, luminance(v[0], v[1], v[2]));
  }
  return std::max(options.shadow_sigmas * std::sqrt(options.noise.a),
                  options.shadow_fraction * y_max);
}

// gather_samples with the threshold given.
GatheredSamples gather_above(const capture::ReflectanceField& field,
                             const capture::ValidLights& valid, const NormalOptions& options, int x,
                             int y, double threshold, Sample* samples,
                             std::vector<Eigen::Vector3d>* shadowed) {
  const float* px = field.pixel(x, y);
  GatheredSamples out;
  std::optional<capture::PixelLightDirs> dir_to;  // Near LEDs only: from this pixel.
  if (valid.near) dir_to.emplace(field, x, y);
  const auto dir = [&](size_t i) {
    return dir_to ? (*dir_to)(valid.index[i]) : valid.dirs_in_stage[i];
  };
  if (shadowed) shadowed->clear();
  for (size_t i = 0; i < valid.index.size(); ++i) {
    const int light = valid.index[i];
    const float* v = px + 3 * size_t(light);
    if (capture::is_saturated(field.lights()[light], v)) {
      ++out.saturated;
      continue;
    }
    const double lum = luminance(v[0], v[1], v[2]);
    if (!(lum > threshold) || !std::isfinite(lum)) {
      if (shadowed && std::isfinite(lum)) shadowed->push_back(dir(i));
      continue;
    }
    Sample& s = samples[out.count++];
    s.l = dir(i);
    for (int c = 0; c < 3; ++c) {
      s.v[c] = v[c];
      s.inv_sigma[c] = 1 / std::sqrt(options.noise.variance(v[c]));
    }
  }
  return out;
}

}  // namespace

GatheredSamples gather_samples(const capture::ReflectanceField& field,
                               const capture::ValidLights& valid, const NormalOptions& options,
                               int x, int y, Sample* samples,
                               std::vector<Eigen::Vector3d>* shadowed) {
  return gather_above(field, valid, options, x, y,
                      shadow_threshold(field.pixel(x, y), valid, options), samples, shadowed);
}

Eigen::Vector3d lambert_albedo(const Sample* samples, int count, const Eigen::Vector3d& n) {
  Eigen::Vector3d albedo;
  for (int c = 0; c < 3; ++c) {
    double sxx = 0, sxy = 0;
    for (int i = 0; i < count; ++i) {
      const double shade = std::max(0.0, n.dot(samples[i].l)) / kPi;
      const double w = samples[i].inv_sigma[c] * samples[i].inv_sigma[c];
      sxx += w * shade * shade;
      sxy += w * shade * samples[i].v[c];
    }
    albedo(c) = std::max(sxx > 0 ? sxy / sxx : 0.0, 1e-4);
  }
  return albedo;
}

Eigen::Vector3d normal_at(const NormalMap& normals, int x, int y) {
  return Eigen::Vector3d(normals.normal.at(x, y, 0), normals.normal.at(x, y, 1),
                         normals.normal.at(x, y, 2))
      .normalized();
}

Eigen::Vector3d view_dir_at(const std::vector<Eigen::Vector3d>& per_pixel, size_t i) {
  return per_pixel.empty() ? Eigen::Vector3d(0, 0, 1) : per_pixel[i].normalized();
}

std::string check_view_dirs(const std::vector<Eigen::Vector3d>& per_pixel, int width, int height) {
  const size_t pixels = size_t(width) * height;
  if (per_pixel.empty() || per_pixel.size() == pixels) return {};
  return "view_dir_per_pixel: expected " + std::to_string(pixels) + " directions, got " +
         std::to_string(per_pixel.size());
}

int gather_with_dim_samples(const capture::ReflectanceField& field,
                            const capture::ValidLights& valid, const NormalOptions& options, int x,
                            int y, const std::function<double(const Eigen::Vector3d& l)>& predicted,
                            Sample* samples) {
  const double threshold = shadow_threshold(field.pixel(x, y), valid, options);
  const double ceiling = threshold + kDimMarginSigmas * std::sqrt(options.noise.a);
  // Every usable sample above zero, the dim ones included. Not below: those too let some fits of
  // a dark capture run off (the bench's dark lapse, 4 of 25 steps: the step fits' relative error
  // 0.09 -> 3.7 at the captured steps, on a lobe no sample held).
  const int all = gather_above(field, valid, options, x, y, 0.0, samples, nullptr).count;
  int kept = 0, readmitted = 0;
  for (int i = 0; i < all; ++i) {
    const Sample& s = samples[i];
    const double measured = luminance(s.v[0], s.v[1], s.v[2]);
    if (!(measured > threshold)) {
      const double p = predicted(s.l);
      const double sigma = std::sqrt(options.noise.variance(std::max(p, 0.0)));
      if (!(p <= ceiling) || !(std::abs(measured - p) <= kDimAgreementSigmas * sigma)) continue;
      ++readmitted;
    }
    samples[kept++] = s;
  }
  return readmitted > 0 ? kept : 0;
}

}  // namespace ls::relight::pixel
