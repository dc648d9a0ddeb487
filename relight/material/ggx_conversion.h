#pragma once
// Fitted models (relight/fit/fit.h) as the material other renderers take: the glTF 2.0
// metallic-roughness BRDF, dielectric (metallic 0), with KHR_materials_specular's strength. The
// conversion is a fit: per pixel, the GGX material closest to the fitted model over the hemisphere.
//
// The target BRDF (glTF 2.0 Appendix B with KHR_materials_specular), in 1/sr, cos(theta_i) not
// inside (as physics/brdf.h), directions as there (wi toward the light, wo toward the viewer):
//   f = (1 - w F) base / pi + w F D V
//   F = f0 + (1 - f0) (1 - |wo.h|)^5, f0 = min(0.04 * specularColorFactor, 1): one value for the
//       whole material, the pixels' strength in w (specularFactor x specularTexture.a) in [0, 1]
//   D = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2), a = roughness^2 (GGX / Trowbridge-Reitz)
//   V = 0.5 / (n.wi sqrt((n.wo)^2 (1 - a^2) + a^2) + n.wo sqrt((n.wi)^2 (1 - a^2) + a^2))
// MaterialX's Standard Surface has the same lobes (specular = w, specular_IOR from f0).
//
// The fit: w and roughness of each distinct lobe (k_s, m) against the Torrance-Sparrow lobe alone,
// over lights spread over the hemisphere plus rings around the mirror direction, each sample
// weighted by its solid angle, at views 0, 30 and 60 degrees from the normal; then base per
// channel by linear least squares of the whole BRDF over the hemisphere's lights. Its error per
// pixel: the relative RMS difference of f cos(theta_i) over the hemisphere's lights and the three
// views, all channels (what an environment render of the two materials would differ by).
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <vector>

#include "lightstage/image.h"
#include "physics/brdf.h"
#include "relight/fit/fit.h"

namespace ls::relight {

// The dielectric F0 of glTF's default index of refraction 1.5.
inline constexpr double kGltfDielectricF0 = 0.04;
inline constexpr double kGgxMinRoughness = 0.02;

// The GGX material's BRDF value per channel (1/sr, cos not inside); 0 below either horizon.
template <class T>
physics::brdf::Vec3<T> ggx_brdf(const physics::brdf::Geometry<T>& g, const Eigen::Vector3d& base,
                                double roughness, double strength, double f0) {
  using std::sqrt;
  if (!g.above()) return physics::brdf::Vec3<T>::Zero();
  const T len2 = T(2) + T(2) * g.cos_io;
  const T inv_len = len2 > T(1e-12) ? T(1) / sqrt(len2) : T(0);
  const T cos_h = (g.cos_i + g.cos_o) * inv_len;
  const T cos_oh = (T(1) + g.cos_io) * inv_len;
  const double a = roughness * roughness, a2 = a * a;
  const T dd = cos_h * cos_h * T(a2 - 1) + T(1);
  const T d = T(a2) / (T(physics::brdf::kPi) * dd * dd);
  const T v = T(0.5) / (g.cos_i * sqrt(g.cos_o * g.cos_o * T(1 - a2) + T(a2)) +
                        g.cos_o * sqrt(g.cos_i * g.cos_i * T(1 - a2) + T(a2)));
  const T one_minus = T(1) - cos_oh;
  const T m2 = one_minus * one_minus;
  const T fresnel = T(f0) + T(1 - f0) * m2 * m2 * one_minus;
  const T specular = T(strength) * fresnel * d * v;
  const T diffuse_weight = (T(1) - T(strength) * fresnel) * T(1.0 / physics::brdf::kPi);
  return base.cast<T>() * diffuse_weight + physics::brdf::Vec3<T>::Constant(specular);
}

struct GgxConversion {
  int width = 0, height = 0;
  // Per pixel, row-major; flagged pixels (no fitted model) hold base 0, roughness 1, strength 0
  // and a flat normal, and are not counted below.
  Image base_color;  // 3 channels, linear, [0, 1].
  Image roughness;   // 1 channel, glTF's perceptual roughness (a = roughness^2), [0.02, 1].
  Image strength;    // 1 channel, w in [0, 1].
  Image normal;      // 3 channels, unit, the fit's (stage frame: +X right, +Y up, +Z to camera).
  Image error;       // 1 channel, relative RMS error of the conversion (0 where flagged).
  std::vector<uint8_t> converted;  // Per pixel: 1 where a fitted pixel was converted.
  double f0 = kGltfDielectricF0;   // The material's F0 (specularColorFactor = f0 / 0.04).
  int pixels = 0;                  // Fitted pixels converted.
  double median_error = 0, p95_error = 0, max_error = 0;  // Over those pixels.
  int distinct_lobes = 0;                                 // Lobe fits made.
};

// Converts every fitted pixel of `maps`. k_s is clamped to max_specular_albedo first, as renders
// do (ModelRenderOptions). Rows in parallel (TBB).
GgxConversion convert_to_ggx(const ModelMaps& maps,
                             double max_specular_albedo = kDefaultMaxSpecularAlbedo);

}  // namespace ls::relight
