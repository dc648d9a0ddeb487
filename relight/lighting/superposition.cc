#include "relight/lighting/superposition.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "lightstage/errors.h"

namespace ls::relight {

namespace {
constexpr int kBlock = 8;
constexpr double kOutlierSigmas = 6.0;
constexpr double kLitSigmas = 20.0;
}  // namespace

PlayedRelit relight_played(const capture::ReflectanceField& field,
                           const std::vector<Eigen::Vector3f>& weight_rgb,
                           const PixelGain& pixel_gain) {
  LS_CHECK(int(weight_rgb.size()) == field.num_lights(), "one weight per field light");
  const int w = field.width(), h = field.height(), n = field.num_lights();
  const capture::FieldNoise& noise = field.noise;
  PlayedRelit out{Image(w, h, 3), Image(w, h, 3), Image(w, h, 1, 1.0f)};
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < w; ++x) {
        const float* values = field.pixel(x, y);
        double sum[3] = {0, 0, 0}, variance[3] = {0, 0, 0};
        for (int l = 0; l < n; ++l) {
          const Eigen::Vector3f& weight = weight_rgb[size_t(l)];
          if (weight.maxCoeff() <= 0) continue;
          const float* rgb = values + 3 * size_t(l);
          if (capture::is_saturated(field.lights()[size_t(l)], rgb)) out.usable.at(x, y, 0) = 0.0f;
          const double scale = pixel_gain ? 1.0 / pixel_gain(l, x, y) : 1.0;
          for (int c = 0; c < 3; ++c) {
            const double w = weight[c] * scale;
            sum[c] += w * rgb[c];
            variance[c] += w * w *
                           (noise.read_variance +
                            noise.shot_variance_per_unit * std::max(0.0, double(rgb[c])));
          }
        }
        for (int c = 0; c < 3; ++c) {
          out.radiance.at(x, y, c) = float(sum[c]);
          out.variance.at(x, y, c) = float(variance[c]);
        }
      }
    }
  });
  return out;
}

SuperpositionCheck compare_played(const capture::PlayedPhoto& photo, const PlayedRelit& relit) {
  const Image& p = photo.radiance;
  const Image& q = relit.radiance;
  if (p.width != q.width || p.height != q.height) {
    throw InputError("play: the photograph is " + std::to_string(p.width) + "x" +
                     std::to_string(p.height) + ", the field " + std::to_string(q.width) + "x" +
                     std::to_string(q.height) + ": the field is not of this camera's view");
  }
  // Pixels the played light reaches: the relit field above 20 sigma of its noise in some channel
  // (nearer zero, a field's values carry the bias of its noise, up to 0.4 sigma: 2% here).
  auto lit = [&](int x, int y) {
    for (int c = 0; c < 3; ++c) {
      const double v = q.at(x, y, c);
      if (v > 0 && v * v > kLitSigmas * kLitSigmas * relit.variance.at(x, y, c)) return true;
    }
    return false;
  };
  SuperpositionCheck check;
  std::vector<double> z_scores;  // Per block and channel.
  double sum_sq = 0, ref_sq = 0, cross = 0, peak = 0, chi2 = 0;
  long long values = 0;
  for (int by = 0; by + kBlock <= p.height; by += kBlock) {
    for (int bx = 0; bx + kBlock <= p.width; bx += kBlock) {
      double diff[3] = {0, 0, 0}, var[3] = {0, 0, 0};
      int n = 0;
      for (int y = by; y < by + kBlock; ++y) {
        for (int x = bx; x < bx + kBlock; ++x) {
          if (photo.usable.at(x, y, 0) == 0 || relit.usable.at(x, y, 0) == 0) continue;
          if (!lit(x, y)) continue;
          ++n;
          for (int c = 0; c < 3; ++c) {
            const double d = double(p.at(x, y, c)) - q.at(x, y, c);
            diff[c] += d;
            var[c] += double(photo.variance.at(x, y, c)) + relit.variance.at(x, y, c);
            sum_sq += d * d;
            ref_sq += double(q.at(x, y, c)) * q.at(x, y, c);
            cross += double(p.at(x, y, c)) * q.at(x, y, c);
            peak = std::max(peak, double(q.at(x, y, c)));
            ++values;
          }
        }
      }
      if (n < kBlock * kBlock / 2) continue;  // Mostly untrusted: not judged.
      for (int c = 0; c < 3; ++c) {
        if (!(var[c] > 0)) continue;
        const double z = diff[c] / std::sqrt(var[c]);  // (sum d) / sqrt(sum var).
        chi2 += z * z;
        z_scores.push_back(z);
      }
      ++check.blocks;
    }
  }
  // Nothing lit, or nothing with noise to judge against: no test.
  if (values == 0 || check.blocks == 0 || !(ref_sq > 0) || z_scores.empty()) {
    check.blocks = 0;
    return check;
  }
  const double rmse = std::sqrt(sum_sq / double(values));
  check.relative_rmse = rmse / std::sqrt(ref_sq / double(values));
  check.psnr_db = 20 * std::log10(peak / std::max(rmse, 1e-30));
  check.reduced_chi2 = chi2 / (3.0 * check.blocks);
  check.gain = cross / ref_sq;
  // Outlying blocks against the spread the blocks actually show (1.4826 MAD), never below the
  // noise models' (1): a model that underestimates the noise then raises no alarm, while a change
  // confined to part of the view still stands out.
  std::vector<double> sorted = z_scores;
  const size_t mid = sorted.size() / 2;
  std::nth_element(sorted.begin(), sorted.begin() + long(mid), sorted.end());
  const double median = sorted[mid];
  for (double& z : sorted) z = std::abs(z - median);
  std::nth_element(sorted.begin(), sorted.begin() + long(mid), sorted.end());
  check.noise_scale = std::max(1.0, 1.4826 * sorted[mid]);
  for (const double z : z_scores) {
    check.outlying_blocks += std::abs(z - median) > kOutlierSigmas * check.noise_scale;
  }
  return check;
}

}  // namespace ls::relight
