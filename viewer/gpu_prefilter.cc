#include "viewer/gpu_prefilter.h"

#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "physics/brdf.h"
#include "physics/envmap.h"

namespace ls::viewer::model_prefilter {
namespace {

// The Beckmann reflection lobe about r as a function of c = r.w: D(h) of the half vector between
// r and w at normal incidence (tan^2(theta_h) = (1 - c) / (1 + c)) times the reflection
// Jacobian 1 / (4 cos theta_h); unnormalised. Zero where exp() is below 1e-11.
double beckmann_lobe(double c, double m) {
  const double half_cos2 = 0.5 * (1.0 + c);  // cos^2(theta_h).
  if (half_cos2 <= 1e-6) return 0.0;
  const double x = (1.0 - c) / (1.0 + c) / (m * m);
  if (x > 25.0) return 0.0;
  return std::exp(-x) / (half_cos2 * half_cos2 * std::sqrt(half_cos2));
}

// Integral of beckmann_lobe over the sphere, sr, per level.
const std::array<double, kPrefilterLevels>& lobe_integrals() {
  static const std::array<double, kPrefilterLevels> integrals = [] {
    std::array<double, kPrefilterLevels> out{};
    constexpr int kSteps = 200000;
    for (int j = 0; j < kPrefilterLevels; ++j) {
      double sum = 0;
      for (int i = 0; i < kSteps; ++i) {
        const double theta = physics::brdf::kPi * (i + 0.5) / kSteps;
        sum += beckmann_lobe(std::cos(theta), kLevelRoughness[j]) * std::sin(theta);
      }
      out[j] = 2.0 * physics::brdf::kPi * sum * physics::brdf::kPi / kSteps;
    }
    return out;
  }();
  return integrals;
}

// beckmann_lobe / its integral per level, at kEntries points of r.w from cutoff (where it
// vanishes) to 1, for linear interpolation.
struct LobeTables {
  static constexpr int kEntries = 2048;
  std::array<float, kPrefilterLevels> cutoff{}, inverse_step{};
  std::array<std::array<float, kEntries>, kPrefilterLevels> values{};
};

const LobeTables& lobe_tables() {
  static const LobeTables tables = [] {
    LobeTables out;
    const std::array<double, kPrefilterLevels>& integrals = lobe_integrals();
    for (int j = 0; j < kPrefilterLevels; ++j) {
      const double m = kLevelRoughness[j], x = 25.0 * m * m;
      const double cutoff = (1 - x) / (1 + x), step = (1 - cutoff) / (LobeTables::kEntries - 1);
      out.cutoff[j] = float(cutoff);
      out.inverse_step[j] = float(1 / step);
      for (int i = 0; i < LobeTables::kEntries; ++i) {
        out.values[j][i] = float(beckmann_lobe(cutoff + i * step, m) / integrals[j]);
      }
    }
    return out;
  }();
  return tables;
}

// Real SH basis, bands 0-2 (the shader's sh_eval order).
std::array<double, 9> sh_basis(const Eigen::Vector3d& d) {
  const double x = d.x(), y = d.y(), z = d.z();
  return {0.282095,
          0.488603 * y,
          0.488603 * z,
          0.488603 * x,
          1.092548 * x * y,
          1.092548 * y * z,
          0.315392 * (3 * z * z - 1),
          1.092548 * x * z,
          0.546274 * (x * x - y * y)};
}

}  // namespace

// Directional albedo of the lobes under unit radiance, integral of f cos_i over the hemisphere
// (1/k_s), tabulated at cos_o = (i / 31)^2 (x) and m = j / 31 (y; m >= 0.01); RGBA: r Torrance-
// Sparrow, g Phong with exponent 2/m^2 - 2 clamped to [1, 1e4] as the shader, b Oren-Nayar's
// B factor under uniform light (depends on cos_o only). Importance sampled
// on a 64 x 64 stratified grid: the Beckmann half vector for Torrance-Sparrow, cos^n about the
// mirror direction for Phong.
const std::vector<float>& lobe_albedo_table() {
  static const std::vector<float> table = [] {
    constexpr int kN = kLobeAlbedoSize, kSamples = 64;
    std::vector<float> out(std::size_t(kN) * kN * 4, 0.0f);
    tbb::parallel_for(0, kN, [&](int j) {
      const double m = std::max(0.01, double(j) / (kN - 1));
      const double exponent = std::clamp(2.0 / (m * m) - 2.0, 1.0, 1e4);
      for (int i = 0; i < kN; ++i) {
        // sqrt spacing in cos_o: the lobes' albedo changes fastest at grazing.
        const double cos_o = std::max(1e-3, std::pow(double(i) / (kN - 1), 2));
        const Eigen::Vector3d wo(std::sqrt(1 - cos_o * cos_o), 0, cos_o);
        const Eigen::Vector3d mirror(-wo.x(), 0, cos_o);
        // Orthonormal frame about the mirror direction.
        const Eigen::Vector3d t1 = Eigen::Vector3d(0, 1, 0), t2 = mirror.cross(t1).normalized();
        double ts = 0, ph = 0;
        for (int a = 0; a < kSamples; ++a) {
          const double u1 = (a + 0.5) / kSamples;
          for (int b = 0; b < kSamples; ++b) {
            const double phi = 2 * physics::brdf::kPi * (b + 0.5) / kSamples;
            // Torrance-Sparrow: h ~ D(h) cos theta_h; pdf(wi) = D cos theta_h / (4 wo.h).
            const double tan_h = m * std::sqrt(-std::log(1 - u1));
            const double cos_h = 1 / std::sqrt(1 + tan_h * tan_h), sin_h = tan_h * cos_h;
            const Eigen::Vector3d h(sin_h * std::cos(phi), sin_h * std::sin(phi), cos_h);
            const double wo_h = wo.dot(h);
            const Eigen::Vector3d wi = 2 * wo_h * h - wo;
            if (wo_h > 0 && wi.z() > 0) {
              const double d = std::exp(-tan_h * tan_h / (m * m)) /
                               (physics::brdf::kPi * m * m * std::pow(cos_h, 4));
              const auto g = physics::brdf::Geometry<double>::from_local(wi, wo);
              ts += physics::brdf::torrance_sparrow(g, m) * wi.z() * 4 * wo_h / (d * cos_h);
            }
            // Phong: wi ~ (n+1)/(2 pi) cos^n(alpha) about the mirror direction.
            const double cos_a = std::pow(u1, 1 / (exponent + 1));
            const double sin_a = std::sqrt(std::max(0.0, 1 - cos_a * cos_a));
            const Eigen::Vector3d wp =
                cos_a * mirror + sin_a * (std::cos(phi) * t1 + std::sin(phi) * t2);
            if (wp.z() > 0) {
              const auto g = physics::brdf::Geometry<double>::from_local(wp, wo);
              const double pdf =
                  (exponent + 1) / (2 * physics::brdf::kPi) * std::pow(cos_a, exponent);
              if (pdf > 0) ph += physics::brdf::phong(g, exponent) * wp.z() / pdf;
            }
          }
        }
        // Oren-Nayar's B factor, max(0, wi.wo - cos_i cos_o) / max(cos_i, cos_o), averaged over
        // wi ~ cos_i / pi (uniform light): independent of m, stored in every row.
        double on = 0;
        for (int a = 0; a < kSamples; ++a) {
          const double sin_i = std::sqrt((a + 0.5) / kSamples);
          const double cos_i = std::sqrt(1 - sin_i * sin_i);
          for (int b = 0; b < kSamples; ++b) {
            const double phi = 2 * physics::brdf::kPi * (b + 0.5) / kSamples;
            const Eigen::Vector3d wi(sin_i * std::cos(phi), sin_i * std::sin(phi), cos_i);
            on += std::max(0.0, wi.dot(wo) - cos_i * cos_o) / std::max(cos_i, cos_o);
          }
        }
        float* texel = &out[(std::size_t(j) * kN + i) * 4];
        texel[0] = float(ts / (kSamples * kSamples));
        texel[1] = float(ph / (kSamples * kSamples));
        texel[2] = float(on / (kSamples * kSamples));
      }
    });
    return out;
  }();
  return table;
}

// FNV-1a over the lights: rebuild the prefiltered lighting only when they changed.
uint64_t fingerprint(const relight::LightingForModels& lights) {
  uint64_t hash = 1469598103934665603ull;
  auto add = [&hash](const void* data, std::size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) hash = (hash ^ p[i]) * 1099511628211ull;
  };
  const std::size_t count = lights.dirs_in_stage.size();
  add(&count, sizeof(count));
  if (count > 0) {
    add(lights.dirs_in_stage.data(), count * sizeof(Eigen::Vector3f));
    add(lights.irradiance_rgb.data(), count * sizeof(Eigen::Vector3f));
  }
  return hash;
}

PrefilteredLighting prefilter(const relight::LightingForModels& lights) {
  PrefilteredLighting out;
  const std::size_t count = lights.dirs_in_stage.size();
  std::vector<Eigen::Vector3d> dirs(count), irradiance(count);
  for (std::size_t k = 0; k < count; ++k) {
    dirs[k] = lights.dirs_in_stage[k].cast<double>().normalized();
    irradiance[k] = lights.irradiance_rgb[k].cast<double>();
    if (!dirs[k].allFinite()) irradiance[k].setZero(), dirs[k] = Eigen::Vector3d(0, 0, 1);
  }
  // Irradiance SH: L_lm = sum_k E_k Y_lm(w_k) (each light a delta of irradiance E_k), times the
  // clamped cosine's A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4.
  constexpr double kBand[9] = {
      physics::brdf::kPi,         2 * physics::brdf::kPi / 3, 2 * physics::brdf::kPi / 3,
      2 * physics::brdf::kPi / 3, physics::brdf::kPi / 4,     physics::brdf::kPi / 4,
      physics::brdf::kPi / 4,     physics::brdf::kPi / 4,     physics::brdf::kPi / 4};
  std::array<Eigen::Vector3d, 9> sh;
  sh.fill(Eigen::Vector3d::Zero());
  for (std::size_t k = 0; k < count; ++k) {
    const std::array<double, 9> y = sh_basis(dirs[k]);
    for (int i = 0; i < 9; ++i) sh[i] += irradiance[k] * y[i];
  }
  for (int i = 0; i < 9; ++i) {
    for (int c = 0; c < 3; ++c) out.sh_irradiance[i * 3 + c] = float(sh[i][c] * kBand[i]);
  }
  // Each level: sum_k E_k K(r.w_k) / integral K: the radiance of the lights seen through the lobe.
  // K / integral K is tabulated over r.w from where it vanishes to 1 (a lookup instead of exp and
  // sqrt: 3x faster), in float.
  const LobeTables& tables = lobe_tables();
  std::vector<Eigen::Vector3f> dirs_f(count), irradiance_f(count);
  for (std::size_t k = 0; k < count; ++k) {
    dirs_f[k] = dirs[k].cast<float>();
    irradiance_f[k] = irradiance[k].cast<float>();
  }
  const std::size_t level_texels = std::size_t(kPrefilterWidth) * kPrefilterHeight;
  out.levels.assign(level_texels * kPrefilterLevels * 4, 0.0f);
  tbb::parallel_for(0, kPrefilterHeight, [&](int y) {
    for (int x = 0; x < kPrefilterWidth; ++x) {
      const Eigen::Vector3f r = physics::EnvironmentMap::direction((x + 0.5) / kPrefilterWidth,
                                                                   (y + 0.5) / kPrefilterHeight)
                                    .cast<float>();
      std::array<Eigen::Vector3f, kPrefilterLevels> sum;
      sum.fill(Eigen::Vector3f::Zero());
      for (std::size_t k = 0; k < count; ++k) {
        const float c = r.dot(dirs_f[k]);
        for (int j = kPrefilterLevels - 1; j >= 0 && c > tables.cutoff[j]; --j) {
          const float t = std::min((c - tables.cutoff[j]) * tables.inverse_step[j],
                                   float(LobeTables::kEntries - 1) - 1e-3f);
          const int i = int(t);
          const float* entry = &tables.values[j][i];
          sum[j] += irradiance_f[k] * (entry[0] + (t - float(i)) * (entry[1] - entry[0]));
        }
      }
      for (int j = 0; j < kPrefilterLevels; ++j) {
        float* texel = &out.levels[(j * level_texels + std::size_t(y) * kPrefilterWidth + x) * 4];
        for (int c = 0; c < 3; ++c) texel[c] = sum[j][c];
        texel[3] = 1.0f;
      }
    }
  });
  return out;
}

}  // namespace ls::viewer::model_prefilter
