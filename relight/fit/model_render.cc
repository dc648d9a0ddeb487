#include "relight/fit/model_render.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "lightstage/errors.h"
#include "physics/brdf.h"

namespace ls::relight {
namespace {

// Directions as structure-of-arrays so the Lambert sum vectorises.
struct Lights {
  std::vector<float> x, y, z, r, g, b;
  int count = 0;
};

Lights to_soa(const LightingForModels& lighting) {
  Lights out;
  out.count = int(lighting.dirs_in_stage.size());
  for (int k = 0; k < out.count; ++k) {
    const Eigen::Vector3f& d = lighting.dirs_in_stage[k];
    const Eigen::Vector3f& e = lighting.irradiance_rgb[k];
    out.x.push_back(d.x());
    out.y.push_back(d.y());
    out.z.push_back(d.z());
    out.r.push_back(e.x());
    out.g.push_back(e.y());
    out.b.push_back(e.z());
  }
  return out;
}

// sum_k E_k max(0, n . w_k): the cosine-weighted irradiance at normal n. Eight independent lanes
// so the loop vectorises without -ffast-math.
Eigen::Vector3f cosine_irradiance(const Lights& lights, const Eigen::Vector3f& n) {
  constexpr int kLanes = 8;
  float ar[kLanes] = {}, ag[kLanes] = {}, ab[kLanes] = {};
  int k = 0;
  for (; k + kLanes <= lights.count; k += kLanes) {
    for (int j = 0; j < kLanes; ++j) {
      const float c = std::max(
          0.0f, n.x() * lights.x[k + j] + n.y() * lights.y[k + j] + n.z() * lights.z[k + j]);
      ar[j] += c * lights.r[k + j];
      ag[j] += c * lights.g[k + j];
      ab[j] += c * lights.b[k + j];
    }
  }
  for (int j = 0; k + j < lights.count; ++j) {
    const float c =
        std::max(0.0f, n.x() * lights.x[k + j] + n.y() * lights.y[k + j] + n.z() * lights.z[k + j]);
    ar[j] += c * lights.r[k + j];
    ag[j] += c * lights.g[k + j];
    ab[j] += c * lights.b[k + j];
  }
  Eigen::Vector3f sum(0, 0, 0);
  for (int j = 0; j < kLanes; ++j) sum += Eigen::Vector3f(ar[j], ag[j], ab[j]);
  return sum;
}

// A fitted pixel's model, read from its map channels.
struct PixelModel {
  FitModel model = FitModel::kNone;
  Eigen::Vector3f n, albedo;
  float sigma = 0, ks = 0, roughness = 0, exponent = 0;
  bool oren_nayar = false, lobe = false;

  // False when the pixel has no normal.
  bool read(const float* m, float max_ks) {
    model = FitModel(int(m[kMapModel]));
    n = Eigen::Vector3f(m[kMapNormalX], m[kMapNormalY], m[kMapNormalZ]);
    const float norm = n.norm();
    if (!(norm > 0)) return false;
    n /= norm;
    albedo = Eigen::Vector3f(m[kMapAlbedoR], m[kMapAlbedoG], m[kMapAlbedoB]);
    sigma = m[kMapSigma];
    ks = std::min(m[kMapKs], max_ks);
    roughness = std::max(m[kMapRoughness], 1e-3f);
    // Phong's exponent from the stored equivalent roughness m = sqrt(2 / (exponent + 2)).
    exponent = std::clamp(2.0f / (roughness * roughness) - 2.0f, 1.0f, 1e4f);
    oren_nayar = model == FitModel::kOrenNayar;
    lobe =
        ks > 0 && (model == FitModel::kLambertTorranceSparrow || model == FitModel::kLambertPhong);
    return true;
  }
  // The diffuse BRDF per unit albedo, 1/sr.
  float diffuse(const physics::brdf::Geometry<float>& g) const {
    return oren_nayar ? physics::brdf::oren_nayar(g, sigma) : float(1.0 / std::numbers::pi);
  }
  // The lobe's BRDF per unit k_s, 1/sr.
  float lobe_f(const physics::brdf::Geometry<float>& g) const {
    return model == FitModel::kLambertTorranceSparrow
               ? physics::brdf::torrance_sparrow(g, roughness)
               : physics::brdf::phong(g, exponent);
  }
};

// Which lights a pixel's shadowed LEDs stand for: each light takes its nearest LED's visibility.
struct LightShadows {
  const FitShadows* shadows = nullptr;  // Null: every light lights every pixel.
  std::vector<int> led_of;              // Per light.
  std::vector<std::vector<int>> lights_of_led;

  LightShadows(const FitShadows& fit_shadows, const LightingForModels& lighting) {
    if (fit_shadows.empty()) return;
    shadows = &fit_shadows;
    led_of = nearest_leds(fit_shadows.led_dirs_in_stage, lighting.dirs_in_stage);
    lights_of_led.resize(fit_shadows.led_dirs_in_stage.size());
    for (size_t k = 0; k < led_of.size(); ++k) lights_of_led[size_t(led_of[k])].push_back(int(k));
  }
};

// A pixel's shadow bits; `any` false when every LED lights it.
struct PixelShadows {
  std::vector<uint32_t> words;
  bool any = false;
  float shadow(int led) const {
    return float(FitShadows::level(words.data(), led)) * (1.0f / FitShadows::kShadowLevels);
  }
};

// sum_k shadow_k E_k max(0, n . w_k): the cosine-weighted irradiance the pixel's shadows take.
Eigen::Vector3f shadowed_cosine_irradiance(const Lights& lights, const LightShadows& light_shadows,
                                           const PixelShadows& pixel, const Eigen::Vector3f& n) {
  Eigen::Vector3f sum(0, 0, 0);
  for (size_t led = 0; pixel.any && led < light_shadows.lights_of_led.size(); ++led) {
    const float shadow = pixel.shadow(int(led));
    if (shadow == 0) continue;
    for (const int k : light_shadows.lights_of_led[led]) {
      const float c =
          std::max(0.0f, n.x() * lights.x[k] + n.y() * lights.y[k] + n.z() * lights.z[k]);
      sum += (shadow * c) * Eigen::Vector3f(lights.r[k], lights.g[k], lights.b[k]);
    }
  }
  return sum;
}

// One pixel's outgoing radiance under the lights its shadows leave. Returns 0 when the pixel faces
// away.
Eigen::Vector3f shade(const Lights& lights, const PixelModel& p, const Eigen::Vector3f& wo,
                      const LightShadows& light_shadows, const PixelShadows& pixel) {
  const float cos_o = p.n.dot(wo);
  if (!(cos_o > 0)) return Eigen::Vector3f::Zero();  // Every BRDF is 0 below the surface.
  const auto lambert_irradiance = [&] {
    return Eigen::Vector3f(cosine_irradiance(lights, p.n) -
                           shadowed_cosine_irradiance(lights, light_shadows, pixel, p.n));
  };
  if (p.model == FitModel::kLambert) {
    return p.albedo.cwiseProduct(lambert_irradiance()) * float(1.0 / std::numbers::pi);
  }
  // A Lambertian diffuse part is the (vectorised) cosine-weighted sum; only the rest is per light.
  Eigen::Vector3f diffuse = p.oren_nayar ? Eigen::Vector3f(0, 0, 0)
                                         : Eigen::Vector3f(lambert_irradiance() / std::numbers::pi);
  Eigen::Vector3f specular_rgb(0, 0, 0);  // sum E cos f_lobe; the lobe is white (k_s one number).
  for (int k = 0; (p.oren_nayar || p.lobe) && k < lights.count; ++k) {
    const Eigen::Vector3f wi(lights.x[k], lights.y[k], lights.z[k]);
    const float cos_i = p.n.dot(wi);
    if (!(cos_i > 0)) continue;
    const float lit = pixel.any ? 1 - pixel.shadow(light_shadows.led_of[size_t(k)]) : 1.0f;
    if (lit == 0) continue;
    const physics::brdf::Geometry<float> g{cos_i, cos_o, wi.dot(wo)};
    const Eigen::Vector3f e = lit * Eigen::Vector3f(lights.r[k], lights.g[k], lights.b[k]);
    if (p.oren_nayar) diffuse += e * (p.diffuse(g) * cos_i);
    if (p.lobe) specular_rgb += e * (p.lobe_f(g) * cos_i);
  }
  Eigen::Vector3f out = p.albedo.cwiseProduct(diffuse) + p.ks * specular_rgb;
  // A lobe evaluated at grazing angles can overflow float; never let that out as inf/NaN.
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(out[c])) out[c] = 0;
  }
  return out;
}

}  // namespace

Eigen::Vector3f model_brdf(const float* m, const physics::brdf::Geometry<float>& g, float max_ks) {
  PixelModel p;
  if (!p.read(m, max_ks) || !g.above()) return Eigen::Vector3f::Zero();
  Eigen::Vector3f out = p.albedo * p.diffuse(g);
  if (p.lobe) out.array() += p.ks * p.lobe_f(g);
  return out;
}

Eigen::Vector3f model_radiance(const float* m, const Eigen::Vector3f& wi, const Eigen::Vector3f& wo,
                               float max_ks) {
  PixelModel p;
  if (!p.read(m, max_ks)) return Eigen::Vector3f::Zero();
  const float cos_i = p.n.dot(wi), cos_o = p.n.dot(wo);
  if (!(cos_i > 0 && cos_o > 0)) return Eigen::Vector3f::Zero();
  const physics::brdf::Geometry<float> g{cos_i, cos_o, wi.dot(wo)};
  Eigen::Vector3f out = p.albedo * (p.diffuse(g) * cos_i);
  if (p.lobe) out.array() += p.ks * p.lobe_f(g) * cos_i;
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(out[c])) out[c] = 0;
  }
  return out;
}

Image render_models(const ModelMaps& maps, const LightingForModels& lighting,
                    const ModelRenderOptions& options) {
  const Image& src = maps.maps;
  const int width = src.width, height = src.height;
  LS_CHECK(src.channels == kMapChannelCount, "model maps have " + std::to_string(src.channels) +
                                                 " channels, expected " +
                                                 std::to_string(int(kMapChannelCount)));
  LS_CHECK(lighting.dirs_in_stage.size() == lighting.irradiance_rgb.size(),
           "lighting has " + std::to_string(lighting.dirs_in_stage.size()) + " directions and " +
               std::to_string(lighting.irradiance_rgb.size()) + " irradiances");
  if (!options.view_dir_per_pixel.empty() &&
      options.view_dir_per_pixel.size() != src.num_pixels()) {
    throw InputError("model render options: view_dir_per_pixel: expected " +
                     std::to_string(src.num_pixels()) + " directions, got " +
                     std::to_string(options.view_dir_per_pixel.size()));
  }
  const Image* fallback = options.flagged_fallback;
  if (fallback != nullptr &&
      (fallback->width != width || fallback->height != height || fallback->channels < 3)) {
    throw InputError("model render options: flagged_fallback: expected a " + std::to_string(width) +
                     "x" + std::to_string(height) + " image with >= 3 channels, got " +
                     std::to_string(fallback->width) + "x" + std::to_string(fallback->height) +
                     "x" + std::to_string(fallback->channels));
  }
  const Lights lights = to_soa(lighting);
  const FitShadows& shadows = maps.shadows;
  if (!shadows.empty()) {
    LS_CHECK(
        shadows.words.width == width && shadows.words.height == height &&
            shadows.words.channels == FitShadows::words_for(int(shadows.led_dirs_in_stage.size())),
        "model maps: shadows do not fit the maps");
  }
  const LightShadows light_shadows(shadows, lighting);
  Image out(width, height, 3);
  out.channel_names = {"R", "G", "B"};
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    PixelShadows pixel;
    pixel.words.resize(size_t(shadows.words.channels));
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        const float* m = &src.pixels[(size_t(y) * width + x) * kMapChannelCount];
        float* o = &out.at(x, y, 0);
        const int model = int(m[kMapModel]);
        if (model <= int(FitModel::kNone) || model > int(FitModel::kLambertPhong)) {
          for (int c = 0; c < 3; ++c) {
            const float v = fallback != nullptr ? fallback->at(x, y, c) : 0.0f;
            o[c] = std::isfinite(v) ? v : 0.0f;
          }
          continue;
        }
        const Eigen::Vector3f wo =
            options.view_dir_per_pixel.empty()
                ? Eigen::Vector3f(0, 0, 1)
                : options.view_dir_per_pixel[size_t(y) * width + x].normalized().cast<float>();
        PixelModel p;
        if (!p.read(m, options.max_specular_albedo)) {
          o[0] = o[1] = o[2] = 0;
          continue;
        }
        pixel.any = false;
        if (!shadows.empty()) {
          shadows.pixel_words(x, y, pixel.words.data());
          for (int w = 0; w < shadows.words.channels; ++w) pixel.any |= pixel.words[w] != 0;
        }
        const Eigen::Vector3f rgb = shade(lights, p, wo, light_shadows, pixel);
        for (int c = 0; c < 3; ++c) o[c] = rgb[c];
      }
    }
  });
  return out;
}

}  // namespace ls::relight
