// White-target intensity calibration (per-LED irradiance, colour balance and flat field) and the
// flat fields as the build reads them; the mirror-sphere directions are in light_calibration.cc.
#include <Eigen/Dense>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <regex>

#include "capture/light_calibration.h"
#include "lightstage/errors.h"

namespace ls::capture {

namespace {

// The white target's pixels lit by one LED, every options.step-th pixel: (u, v) and the observed
// radiance per channel divided by (albedo / pi * geometry), where geometry is the cosine at the
// target (times the inverse-square fall-off relative to the origin for a near LED).
struct WhiteTargetSamples {
  std::vector<Eigen::Vector2d> uv;
  std::vector<Eigen::Vector3d> q;
  long considered = 0, clipped = 0;
};

template <typename ToUv>
WhiteTargetSamples white_target_samples(const Image& image, const Led& led, const WhitePlane& plane,
                                        const ViewCamera& camera, const IntensityOptions& options,
                                        ToUv to_uv) {
  const Eigen::Vector3d n = plane.normal.normalized();
  const double radiance_per_irradiance = plane.albedo / std::numbers::pi;  // Lambertian, 1/sr.
  const int step = std::max(1, options.step);
  // A plain vector and a flag (not std::optional): GCC 12 warns falsely on optional Eigen.
  const bool near_led = led.distance_m.has_value();
  const Eigen::Vector3d led_pos = led.distance_m.value_or(0.0) * led.dir_in_stage.normalized();
  WhiteTargetSamples out;
  for (int y = step / 2; y < image.height; y += step) {
    for (int x = step / 2; x < image.width; x += step) {
      const Eigen::Vector2d px(x + 0.5, y + 0.5);
      Eigen::Vector3d o, d;
      camera.ray(px, &o, &d);
      const double denom = d.dot(n);
      if (std::abs(denom) < 1e-9) continue;
      const Eigen::Vector3d p = o + ((plane.center_in_stage - o).dot(n) / denom) * d;
      double geometry;
      if (near_led) {
        const Eigen::Vector3d to_led = led_pos - p;
        const double r2 = to_led.squaredNorm();
        geometry = std::max(0.0, n.dot(to_led.normalized())) * led_pos.squaredNorm() / r2;
      } else {
        geometry = std::max(0.0, n.dot(led.dir_in_stage.normalized()));
      }
      if (geometry < 0.05) continue;  // Grazing: the cosine amplifies every error.
      ++out.considered;
      Eigen::Vector3d value;
      bool clip = false, dark = false;
      for (int c = 0; c < 3; ++c) {
        const double v = image.at(x, y, std::min(c, image.channels - 1));
        if (options.saturation_level > 0 && v >= options.saturation_level) clip = true;
        if (!(v > options.min_signal)) dark = true;
        value[c] = v;
      }
      if (clip) {
        ++out.clipped;
        continue;
      }
      if (dark) continue;
      out.uv.push_back(to_uv(px));
      out.q.push_back(value / (radiance_per_irradiance * geometry));
    }
  }
  return out;
}

std::string format_percent(const char* fmt, double value) {
  char buf[256];
  std::snprintf(buf, sizeof buf, fmt, value);
  return buf;
}

}  // namespace

double FlatField::at(double u, double v) const {
  if (coefficients.size() != 6) return 1.0;
  const double m[6] = {1, u, v, u * u, u * v, v * v};
  double s = 0;
  for (int k = 0; k < 6; ++k) s += coefficients[k] * m[k];
  return s;
}

IntensityCalibration calibrate_intensities(const std::vector<const Image*>& images,
                                           const std::vector<std::string>& names,
                                           const Stage& stage, const WhitePlane& plane,
                                           const ViewCamera& camera,
                                           const IntensityOptions& options) {
  LS_CHECK(names.size() == images.size(), "one name per image");
  if (images.size() != stage.leds.size()) {
    throw InputError(stage.source + ": leds: expected one white-target image per LED (" +
                     std::to_string(stage.leds.size()) + "), got " + std::to_string(images.size()));
  }
  const Eigen::Vector2d origin_px = camera.project(Eigen::Vector3d::Zero());
  auto to_uv = [&](const Eigen::Vector2d& px) {
    return Eigen::Vector2d(2.0 * px.x() / camera.width - 1.0, 2.0 * px.y() / camera.height - 1.0);
  };
  const Eigen::Vector2d origin_uv = to_uv(origin_px);
  IntensityCalibration result;
  for (size_t i = 0; i < images.size(); ++i) {
    const Image& image = *images[i];
    const Led& led = stage.leds[i];
    LedIntensityEstimate est;
    est.led_index = int(i);
    auto report = [&](const std::string& what) {
      result.problems.push_back({int(i), -1, names[i], what});
      result.leds.push_back(est);
    };
    if (image.width != camera.width || image.height != camera.height || image.channels < 1) {
      report("image is " + std::to_string(image.width) + "x" + std::to_string(image.height) +
             ", the camera " + std::to_string(camera.width) + "x" + std::to_string(camera.height));
      continue;
    }
    const WhiteTargetSamples samples =
        white_target_samples(image, led, plane, camera, options, to_uv);
    const std::vector<Eigen::Vector2d>& uv = samples.uv;
    const std::vector<Eigen::Vector3d>& q = samples.q;
    const long considered = samples.considered, clipped = samples.clipped;
    if (considered == 0) {
      report("the white target is not lit by this LED (it faces away)");
      continue;
    }
    const double clipped_fraction = double(clipped) / double(considered);
    if (clipped_fraction > options.max_saturated_fraction) {
      report(format_percent("saturated: %.1f%% of the white target is clipped",
                            100.0 * clipped_fraction));
      continue;
    }
    if (uv.size() < 12) {
      report("too few usable pixels on the white target (" + std::to_string(uv.size()) + ")");
      continue;
    }
    // The shape s(u, v) from the channel sum, least squares over the quadratic monomials.
    Eigen::MatrixXd a(uv.size(), 6);
    Eigen::VectorXd sum(uv.size());
    for (size_t k = 0; k < uv.size(); ++k) {
      const double u = uv[k].x(), v = uv[k].y();
      a.row(k) << 1, u, v, u * u, u * v, v * v;
      sum[k] = q[k].sum();
    }
    const Eigen::VectorXd coef = a.colPivHouseholderQr().solve(sum);
    const double u0 = origin_uv.x(), v0 = origin_uv.y();
    const double at_origin = coef[0] + coef[1] * u0 + coef[2] * v0 + coef[3] * u0 * u0 +
                             coef[4] * u0 * v0 + coef[5] * v0 * v0;
    if (!(at_origin > 0) || !coef.allFinite()) {
      report("the white target's fit is not positive at the stage origin");
      continue;
    }
    est.flat_field.coefficients.assign(coef.data(), coef.data() + 6);
    for (double& c : est.flat_field.coefficients) c /= at_origin;
    const Eigen::VectorXd fitted = a * coef;
    est.fit_rms = std::sqrt((sum - fitted).squaredNorm() / double(uv.size())) / sum.mean();
    if (!(est.fit_rms <= options.max_fit_rms)) {
      report(format_percent("the image is not a smoothly lit white plane: its fit leaves %.0f%% ",
                            100.0 * est.fit_rms) +
             format_percent("RMS (at most %.0f%% for a white target lit by one LED); is the target "
                            "in view and lit by this LED alone?",
                            100.0 * options.max_fit_rms));
      continue;
    }
    // Per-channel scale of the shared shape, least squares: E_c = sum(q_c s) / sum(s^2).
    Eigen::Vector3d num = Eigen::Vector3d::Zero();
    double den = 0;
    for (size_t k = 0; k < uv.size(); ++k) {
      const double s = fitted[k] / at_origin;
      num += q[k] * s;
      den += s * s;
    }
    est.irradiance_rgb = num / den;
    est.ok = est.irradiance_rgb.allFinite() && est.irradiance_rgb.minCoeff() > 0;
    if (!est.ok) {
      report("the white target gives a non-positive irradiance");
      continue;
    }
    result.leds.push_back(est);
  }
  return result;
}

StageUpdate apply_intensities(const IntensityCalibration& calibration, Stage* stage) {
  StageUpdate update;
  for (const LedIntensityEstimate& e : calibration.leds) {
    if (!e.ok || e.led_index < 0 || e.led_index >= int(stage->leds.size())) continue;
    Led& led = stage->leds[e.led_index];
    led.intensity = e.irradiance_rgb.mean();
    led.color_gain = e.irradiance_rgb / led.intensity;
    ++update.intensities_changed;
  }
  return update;
}

Image flat_field_image(const IntensityCalibration& calibration, const Stage& stage, int width,
                       int height) {
  const int n = int(calibration.leds.size());
  Image out(width, height, std::max(n, 1), 1.0f);
  out.channel_names.clear();
  for (int l = 0; l < n; ++l) {
    const int idx = calibration.leds[l].led_index;
    const int id = idx >= 0 && idx < int(stage.leds.size()) ? stage.leds[idx].id : idx;
    char name[32];
    std::snprintf(name, sizeof name, "led%03d.Y", id);
    out.channel_names.push_back(name);
    const FlatField& f = calibration.leds[l].flat_field;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const double u = 2.0 * (x + 0.5) / width - 1.0, v = 2.0 * (y + 0.5) / height - 1.0;
        out.at(x, y, l) = float(f.at(u, v));
      }
    }
  }
  if (n == 0) out.channel_names = {"Y"};
  return out;
}

double FlatFieldMaps::at(int led_id, int x, int y, int image_width, int image_height) const {
  const auto it = by_led_id.find(led_id);
  if (it == by_led_id.end() || width <= 0 || height <= 0) return 1.0;
  // The pixel centre in the grid's sample coordinates (sample i's centre at i).
  const double gx = std::clamp((x + 0.5) * width / image_width - 0.5, 0.0, width - 1.0);
  const double gy = std::clamp((y + 0.5) * height / image_height - 0.5, 0.0, height - 1.0);
  const int x0 = std::min(int(gx), width - 1), y0 = std::min(int(gy), height - 1);
  const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
  const double fx = gx - x0, fy = gy - y0;
  const std::vector<float>& m = it->second;
  auto v = [&](int xx, int yy) { return double(m[size_t(yy) * width + xx]); };
  return (1 - fy) * ((1 - fx) * v(x0, y0) + fx * v(x1, y0)) +
         fy * ((1 - fx) * v(x0, y1) + fx * v(x1, y1));
}

FlatFieldMaps read_flat_field(const std::filesystem::path& file, const Stage& stage) {
  const std::string name = file.string();
  const Image image = read_image(file);
  FlatFieldMaps out;
  out.file = file;
  out.width = image.width;
  out.height = image.height;
  static const std::regex pattern(R"(led(\d+)\.Y)");
  for (int c = 0; c < image.channels; ++c) {
    const std::string channel =
        c < int(image.channel_names.size()) ? image.channel_names[c] : "#" + std::to_string(c);
    std::smatch m;
    if (!std::regex_match(channel, m, pattern)) {
      throw InputError(
          name + ": channel '" + channel +
          "': expected a flat field named ledNNN.Y (lightstage calibrate intensities)");
    }
    int id = 0;
    const std::string digits = m[1].str();
    if (std::from_chars(digits.data(), digits.data() + digits.size(), id).ec != std::errc()) {
      throw InputError(name + ": channel '" + channel + "': LED id out of range");
    }
    if (stage.led_index(id) < 0) {
      throw InputError(name + ": channel '" + channel + "': expected an LED of " + stage.source +
                       ", got LED id " + std::to_string(id) + " which it does not have");
    }
    std::vector<float> values(image.num_pixels());
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        const float v = image.at(x, y, c);
        if (!(v > 0) || !std::isfinite(v)) {
          throw InputError(name + ": channel '" + channel + "': expected positive finite values" +
                           ", got " + std::to_string(v) + " at (" + std::to_string(x) + ", " +
                           std::to_string(y) + ")");
        }
        values[size_t(y) * image.width + x] = v;
      }
    }
    if (!out.by_led_id.emplace(id, std::move(values)).second) {
      throw InputError(name + ": channel '" + channel + "': expected once, got twice");
    }
  }
  return out;
}

}  // namespace ls::capture
