#include "relight/fit/model_render.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "lightstage/errors.h"
#include "relight/lighting/brdf.h"

namespace ls::relight {
namespace {

constexpr double kPi = 3.14159265358979323846;

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

// One pixel's outgoing radiance under the lights. Returns 0 when the pixel faces away.
Eigen::Vector3f shade(const Lights& lights, const float* m, const Eigen::Vector3f& wo,
                      float max_ks) {
  const FitModel model = FitModel(int(m[kMapModel]));
  Eigen::Vector3f n(m[kMapNormalX], m[kMapNormalY], m[kMapNormalZ]);
  const float norm = n.norm();
  if (!(norm > 0)) return Eigen::Vector3f::Zero();
  n /= norm;
  const float cos_o = n.dot(wo);
  if (!(cos_o > 0)) return Eigen::Vector3f::Zero();  // Every BRDF is 0 below the surface.
  const Eigen::Vector3f albedo(m[kMapAlbedoR], m[kMapAlbedoG], m[kMapAlbedoB]);
  if (model == FitModel::kLambert) {
    return albedo.cwiseProduct(cosine_irradiance(lights, n)) * float(1.0 / kPi);
  }
  const float sigma = m[kMapSigma];
  const float ks = std::min(m[kMapKs], max_ks);
  const float roughness = std::max(m[kMapRoughness], 1e-3f);
  // Phong's exponent from the stored equivalent roughness m = sqrt(2 / (exponent + 2)).
  const float exponent = std::clamp(2.0f / (roughness * roughness) - 2.0f, 1.0f, 1e4f);
  const bool oren_nayar = model == FitModel::kOrenNayar;
  // A Lambertian diffuse part is the (vectorised) cosine-weighted sum; only the rest is per light.
  Eigen::Vector3f diffuse =
      oren_nayar ? Eigen::Vector3f(0, 0, 0) : Eigen::Vector3f(cosine_irradiance(lights, n) / kPi);
  const bool lobe =
      ks > 0 && (model == FitModel::kLambertTorranceSparrow || model == FitModel::kLambertPhong);
  Eigen::Vector3f specular_rgb(0, 0, 0);  // sum E cos f_lobe; the lobe is white (k_s one number).
  for (int k = 0; (oren_nayar || lobe) && k < lights.count; ++k) {
    const Eigen::Vector3f wi(lights.x[k], lights.y[k], lights.z[k]);
    const float cos_i = n.dot(wi);
    if (!(cos_i > 0)) continue;
    const brdf::Geometry<float> g{cos_i, cos_o, wi.dot(wo)};
    const Eigen::Vector3f e(lights.r[k], lights.g[k], lights.b[k]);
    if (oren_nayar) diffuse += e * (brdf::oren_nayar(g, sigma) * cos_i);
    if (lobe) {
      const float f = model == FitModel::kLambertTorranceSparrow
                          ? brdf::torrance_sparrow(g, roughness)
                          : brdf::phong(g, exponent);
      specular_rgb += e * (f * cos_i);
    }
  }
  Eigen::Vector3f out = albedo.cwiseProduct(diffuse) + ks * specular_rgb;
  // A lobe evaluated at grazing angles can overflow float; never let that out as inf/NaN.
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(out[c])) out[c] = 0;
  }
  return out;
}

}  // namespace

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
  Image out(width, height, 3);
  out.channel_names = {"R", "G", "B"};
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
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
        const Eigen::Vector3f rgb = shade(lights, m, wo, options.max_specular_albedo);
        for (int c = 0; c < 3; ++c) o[c] = rgb[c];
      }
    }
  });
  return out;
}

}  // namespace ls::relight
