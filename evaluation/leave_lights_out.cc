#include "evaluation/leave_lights_out.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "lightstage/errors.h"

namespace ls::evaluation {

namespace {

// Separable 11-tap Gaussian (sigma 1.5), edges clamped, on one channel of an image.
std::vector<double> blur(const std::vector<double>& in, int width, int height) {
  constexpr int kRadius = 5;
  double kernel[2 * kRadius + 1];
  double sum = 0;
  for (int i = -kRadius; i <= kRadius; ++i) sum += kernel[i + kRadius] = std::exp(-i * i / 4.5);
  for (double& k : kernel) k /= sum;
  std::vector<double> tmp(in.size()), out(in.size());
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      double v = 0;
      for (int i = -kRadius; i <= kRadius; ++i) {
        v += kernel[i + kRadius] * in[size_t(y) * width + std::clamp(x + i, 0, width - 1)];
      }
      tmp[size_t(y) * width + x] = v;
    }
  }
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      double v = 0;
      for (int i = -kRadius; i <= kRadius; ++i) {
        v += kernel[i + kRadius] * tmp[size_t(std::clamp(y + i, 0, height - 1)) * width + x];
      }
      out[size_t(y) * width + x] = v;
    }
  }
  return out;
}

}  // namespace

double ssim(const Image& a, const Image& b, double peak) {
  LS_CHECK(a.width == b.width && a.height == b.height && a.channels == b.channels,
           "ssim: image sizes differ");
  const int w = a.width, h = a.height;
  const size_t n = size_t(w) * h;
  if (n == 0 || !(peak > 0)) return 0;
  const double c1 = std::pow(0.01 * peak, 2), c2 = std::pow(0.03 * peak, 2);
  double total = 0;
  for (int c = 0; c < a.channels; ++c) {
    std::vector<double> x(n), y(n), xx(n), yy(n), xy(n);
    for (size_t i = 0; i < n; ++i) {
      x[i] = a.pixels[i * a.channels + c];
      y[i] = b.pixels[i * b.channels + c];
      xx[i] = x[i] * x[i];
      yy[i] = y[i] * y[i];
      xy[i] = x[i] * y[i];
    }
    const auto mx = blur(x, w, h), my = blur(y, w, h), sxx = blur(xx, w, h), syy = blur(yy, w, h),
               sxy = blur(xy, w, h);
    double sum = 0;
    for (size_t i = 0; i < n; ++i) {
      const double vx = sxx[i] - mx[i] * mx[i], vy = syy[i] - my[i] * my[i];
      const double cov = sxy[i] - mx[i] * my[i];
      sum += ((2 * mx[i] * my[i] + c1) * (2 * cov + c2)) /
             ((mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2));
    }
    total += sum / n;
  }
  return total / a.channels;
}

LeaveLightsOutResult leave_lights_out(const capture::ReflectanceField& field,
                                      const CompactBuilder& build,
                                      const LeaveLightsOutOptions& options) {
  if (options.every < 2 || options.offset < 0 || options.offset >= options.every) {
    throw InputError("leave-lights-out: every: expected >= 2 and 0 <= offset < every");
  }
  std::vector<int> training, held_out;
  for (int l = 0; l < field.num_lights(); ++l) {
    const auto& light = field.lights()[l];
    if (!light.valid) continue;
    if (l % options.every == options.offset) {
      if (light.dir_in_stage.normalized().z() > options.min_dir_z) held_out.push_back(l);
    } else {
      training.push_back(l);
    }
  }
  if (held_out.empty()) throw InputError(field.source + ": leave-lights-out: no LED held out");
  const capture::ReflectanceField train = capture::select_lights(field, training);
  const auto t0 = std::chrono::steady_clock::now();
  const std::unique_ptr<relight::CompactField> compact = build(train);
  LeaveLightsOutResult result;
  result.build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  result.name = compact->name();
  result.bytes_per_pixel = compact->bytes_per_pixel();
  result.held_out = int(held_out.size());
  if (options.inspect) options.inspect(*compact);
  result.training = int(training.size());

  double peak = 0;
  for (int l : held_out) {
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        for (int c = 0; c < 3; ++c) peak = std::max<double>(peak, field.at(x, y, l, c));
      }
    }
  }
  double squared = 0, ssim_sum = 0, squared_codes = 0;
  size_t count = 0;
  const auto gain = float(options.display_gain > 0 ? options.display_gain : 1.0 / peak);
  const auto code = [gain](float v) { return srgb8_code(gain * v); };
  Image predicted, reference(field.width(), field.height(), 3);
  for (int l : held_out) {
    compact->relight_into(relight::LightingForModels::directional(field.lights()[l].dir_in_stage,
                                                                  Eigen::Vector3d::Ones()),
                          predicted);
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        for (int c = 0; c < 3; ++c) {
          const float r = field.at(x, y, l, c);
          reference.at(x, y, c) = r;
          const double d = double(predicted.at(x, y, c)) - r;
          squared += d * d;
          const double dc = double(code(predicted.at(x, y, c))) - code(r);
          squared_codes += dc * dc;
          ++count;
        }
      }
    }
    ssim_sum += ssim(predicted, reference, peak);
  }
  const double rmse = std::sqrt(squared / std::max<size_t>(count, 1));
  result.psnr_db = rmse > 0 && peak > 0 ? 20 * std::log10(peak / rmse) : 200.0;
  const double rmse_codes = std::sqrt(squared_codes / std::max<size_t>(count, 1));
  result.psnr_srgb8_db = rmse_codes > 0 ? 20 * std::log10(255.0 / rmse_codes) : 200.0;
  result.ssim = ssim_sum / held_out.size();
  return result;
}

}  // namespace ls::evaluation
