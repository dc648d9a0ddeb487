#include "relight/material/ggx_conversion.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "lightstage/errors.h"
#include "relight/fit/model_render.h"

namespace ls::relight {
namespace {

using physics::brdf::Geometry;
using physics::brdf::kPi;

// The views the material is matched at (degrees from the normal): a material put on another shape
// is seen from every angle, not only the dome camera's.
constexpr double kViewDegrees[] = {0.0, 30.0, 60.0};
constexpr int kHemisphereLights = 128;
// The rings around each view's mirror direction, in lobe widths atan(m), and lights per ring.
constexpr double kRingWidths[] = {0.25, 0.5, 1.0, 1.5, 2.0, 3.0};
constexpr int kRingLights = 8;

// One light-view pair in the normal's frame (+z the normal), with the solid angle it stands for.
struct Pair {
  Geometry<double> g;
  double weight;  // Solid angle of the light's share of the hemisphere (sr).
};

Eigen::Vector3d view_at(double degrees) {
  const double t = degrees * kPi / 180.0;
  return {std::sin(t), 0.0, std::cos(t)};
}

Geometry<double> geometry_of(const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
  return Geometry<double>::from_local(wi, wo);
}

// Lights spread evenly over the upper hemisphere (a Fibonacci spiral, equal solid angles), at each
// view: where the error is measured and the base colour fitted.
std::vector<Pair> hemisphere_pairs() {
  std::vector<Pair> pairs;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (const double view : kViewDegrees) {
    const Eigen::Vector3d wo = view_at(view);
    for (int k = 0; k < kHemisphereLights; ++k) {
      const double z = 1.0 - (k + 0.5) / kHemisphereLights;
      const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
      const Eigen::Vector3d wi(r * std::cos(golden * k), r * std::sin(golden * k), z);
      pairs.push_back({geometry_of(wi, wo), 2.0 * kPi / kHemisphereLights});
    }
  }
  return pairs;
}

// The hemisphere's lights plus rings around each view's mirror direction, sized by the lobe's
// Beckmann m: where a narrow lobe's energy is, which the even spread would step over.
std::vector<Pair> lobe_pairs(const std::vector<Pair>& hemisphere, double m) {
  std::vector<Pair> pairs = hemisphere;
  const double width = std::atan(m);
  for (const double view : kViewDegrees) {
    const Eigen::Vector3d wo = view_at(view);
    const Eigen::Vector3d mirror(-wo.x(), -wo.y(), wo.z());
    Eigen::Vector3d t1 = mirror.cross(Eigen::Vector3d::UnitY()).normalized();
    const Eigen::Vector3d t2 = mirror.cross(t1);
    pairs.push_back({geometry_of(mirror, wo), kPi * std::pow(0.125 * width, 2)});
    double inner = 0.125 * width;
    for (const double ring : kRingWidths) {
      const double angle = ring * width;
      const double outer = angle + 0.5 * (angle - inner);
      // The ring's band of solid angle, shared by its lights.
      const double band = 2.0 * kPi * (std::cos(inner) - std::cos(outer)) / kRingLights;
      for (int k = 0; k < kRingLights; ++k) {
        const double phi = 2.0 * kPi * k / kRingLights;
        const Eigen::Vector3d wi =
            std::cos(angle) * mirror + std::sin(angle) * (std::cos(phi) * t1 + std::sin(phi) * t2);
        if (wi.z() > 0) pairs.push_back({geometry_of(wi.normalized(), wo), band});
      }
      inner = outer;
    }
  }
  return pairs;
}

// A pixel without a lobe has strength 0, where glTF's BRDF ignores the roughness: 0.5 there, at
// which the Disney diffuse of Principled shaders (Blender's, a glTF importer's target) is closest
// to the Lambertian the glTF specifies (at 1 it is ~7% brighter under a studio map).
struct Lobe {
  double strength = 0, roughness = 0.5;
};

// The GGX lobe (w F D V) closest to k_s x the fitted lobe over `pairs` (weighted by solid angle,
// cos_i inside): roughness by a scan and golden-section refinement, w in closed form at each.
Lobe fit_lobe(const float* m, const std::vector<Pair>& pairs, double f0, float max_ks) {
  std::vector<double> target(pairs.size());
  float lobe_only[kMapChannelCount];
  std::copy(m, m + kMapChannelCount, lobe_only);
  lobe_only[kMapAlbedoR] = lobe_only[kMapAlbedoG] = lobe_only[kMapAlbedoB] = 0;
  for (size_t k = 0; k < pairs.size(); ++k) {
    const Geometry<double>& g = pairs[k].g;
    const Geometry<float> gf{float(g.cos_i), float(g.cos_o), float(g.cos_io)};
    target[k] = model_brdf(lobe_only, gf, max_ks)[0] * g.cos_i;
  }
  // chi^2 of the best w at roughness r.
  const auto solve = [&](double r, double* strength) {
    double xy = 0, xx = 0, yy = 0;
    for (size_t k = 0; k < pairs.size(); ++k) {
      const double x =
          ggx_brdf(pairs[k].g, Eigen::Vector3d::Zero(), r, 1.0, f0)[0] * pairs[k].g.cos_i;
      xy += pairs[k].weight * x * target[k];
      xx += pairs[k].weight * x * x;
      yy += pairs[k].weight * target[k] * target[k];
    }
    const double w = xx > 0 ? std::clamp(xy / xx, 0.0, 1.0) : 0.0;
    *strength = w;
    return yy - 2 * w * xy + w * w * xx;
  };
  constexpr int kScan = 40;
  double best_r = 1, best_w = 0, best = solve(1.0, &best_w);
  for (int i = 0; i < kScan; ++i) {
    const double r = kGgxMinRoughness + (1.0 - kGgxMinRoughness) * i / kScan;
    double w = 0;
    const double chi2 = solve(r, &w);
    if (chi2 < best) best = chi2, best_r = r, best_w = w;
  }
  // Golden section within a scan step either side.
  const double step = (1.0 - kGgxMinRoughness) / kScan;
  double lo = std::max(kGgxMinRoughness, best_r - step), hi = std::min(1.0, best_r + step);
  constexpr double kInvPhi = 0.6180339887498949;
  double a = hi - kInvPhi * (hi - lo), b = lo + kInvPhi * (hi - lo), wa = 0, wb = 0;
  double fa = solve(a, &wa), fb = solve(b, &wb);
  for (int i = 0; i < 24; ++i) {
    if (fa < fb) {
      hi = b, b = a, fb = fa, wb = wa;
      a = hi - kInvPhi * (hi - lo);
      fa = solve(a, &wa);
    } else {
      lo = a, a = b, fa = fb, wa = wb;
      b = lo + kInvPhi * (hi - lo);
      fb = solve(b, &wb);
    }
  }
  if (std::min(fa, fb) < best) {
    return fa < fb ? Lobe{wa, a} : Lobe{wb, b};
  }
  return {best_w, best_r};
}

// The material's F0: the largest lobe k_s of the maps (its 99th percentile, against a few
// outliers), so that the strengths w = F0_pixel / f0 stay within [0, 1]; glTF's 0.04 at least.
double material_f0(const ModelMaps& maps, float max_ks) {
  std::vector<float> ks;
  const Image& src = maps.maps;
  for (size_t i = 0; i < src.num_pixels(); ++i) {
    const float* m = &src.pixels[i * src.channels];
    const auto model = FitModel(int(m[kMapModel]));
    if (model == FitModel::kLambertTorranceSparrow || model == FitModel::kLambertPhong) {
      ks.push_back(std::min(m[kMapKs], max_ks));
    }
  }
  if (ks.empty()) return kGltfDielectricF0;
  const auto at = ks.begin() + std::ptrdiff_t(0.99 * double(ks.size() - 1));
  std::nth_element(ks.begin(), at, ks.end());
  return std::clamp(double(*at), kGltfDielectricF0, 1.0);
}

// Keys of a lobe's (k_s, m), so that pixels of one material share one fit: k_s and m to 0.5%.
std::pair<int, int> lobe_key(const float* m) {
  return {int(std::lround(std::log(std::max(m[kMapKs], 1e-6f)) * 200.0)),
          int(std::lround(std::log(std::max(m[kMapRoughness], 1e-3f)) * 200.0))};
}

bool has_lobe(const float* m) {
  const auto model = FitModel(int(m[kMapModel]));
  return m[kMapKs] > 0 &&
         (model == FitModel::kLambertTorranceSparrow || model == FitModel::kLambertPhong);
}

}  // namespace

GgxConversion convert_to_ggx(const ModelMaps& maps, double max_specular_albedo) {
  const Image& src = maps.maps;
  LS_CHECK(src.channels == kMapChannelCount, "model maps have " + std::to_string(src.channels) +
                                                 " channels, expected " +
                                                 std::to_string(int(kMapChannelCount)));
  const float max_ks = float(max_specular_albedo);
  GgxConversion out;
  out.width = src.width;
  out.height = src.height;
  out.base_color = Image(src.width, src.height, 3);
  out.roughness = Image(src.width, src.height, 1);
  out.strength = Image(src.width, src.height, 1);
  out.normal = Image(src.width, src.height, 3);
  out.error = Image(src.width, src.height, 1);
  out.f0 = material_f0(maps, max_ks);
  out.converted.assign(src.num_pixels(), 0);

  // One lobe fit per distinct (k_s, m), in parallel.
  std::map<std::pair<int, int>, size_t> lobe_index;
  std::vector<size_t> lobe_pixel;  // A pixel holding each lobe.
  for (size_t i = 0; i < src.num_pixels(); ++i) {
    const float* m = &src.pixels[i * src.channels];
    if (!has_lobe(m)) continue;
    if (lobe_index.emplace(lobe_key(m), lobe_pixel.size()).second) lobe_pixel.push_back(i);
  }
  const std::vector<Pair> hemisphere = hemisphere_pairs();
  std::vector<Lobe> lobes(lobe_pixel.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, lobes.size()), [&](const auto& range) {
    for (size_t l = range.begin(); l < range.end(); ++l) {
      const float* m = &src.pixels[lobe_pixel[l] * src.channels];
      lobes[l] =
          fit_lobe(m, lobe_pairs(hemisphere, std::max(m[kMapRoughness], 1e-3f)), out.f0, max_ks);
    }
  });
  out.distinct_lobes = int(lobes.size());

  tbb::parallel_for(tbb::blocked_range<int>(0, src.height), [&](const auto& rows) {
    std::vector<Eigen::Vector3d> target(hemisphere.size());
    std::vector<double> diffuse(hemisphere.size()), specular(hemisphere.size());
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < src.width; ++x) {
        const size_t i = size_t(y) * src.width + x;
        const float* m = &src.pixels[i * src.channels];
        float* normal = &out.normal.pixels[i * 3];
        normal[2] = 1;
        out.roughness.pixels[i] = 1;
        if (FitModel(int(m[kMapModel])) == FitModel::kNone) continue;
        const Eigen::Vector3f n(m[kMapNormalX], m[kMapNormalY], m[kMapNormalZ]);
        if (!(n.norm() > 0)) continue;
        Eigen::Map<Eigen::Vector3f> normal_out(normal);
        normal_out = n.normalized();
        const Lobe lobe = has_lobe(m) ? lobes[lobe_index.at(lobe_key(m))] : Lobe{};
        // Base per channel: least squares of the whole BRDF x cos over the hemisphere.
        Eigen::Vector3d xy = Eigen::Vector3d::Zero(), yy = Eigen::Vector3d::Zero();
        double xx = 0;
        for (size_t k = 0; k < hemisphere.size(); ++k) {
          const Geometry<double>& g = hemisphere[k].g;
          const Geometry<float> gf{float(g.cos_i), float(g.cos_o), float(g.cos_io)};
          target[k] = model_brdf(m, gf, max_ks).cast<double>() * g.cos_i;
          const double with_white =
              ggx_brdf(g, Eigen::Vector3d::Ones(), lobe.roughness, lobe.strength, out.f0)[0];
          specular[k] =
              ggx_brdf(g, Eigen::Vector3d::Zero(), lobe.roughness, lobe.strength, out.f0)[0] *
              g.cos_i;
          diffuse[k] = with_white * g.cos_i - specular[k];
          xy += diffuse[k] * (target[k].array() - specular[k]).matrix();
          xx += diffuse[k] * diffuse[k];
          yy += target[k].cwiseProduct(target[k]);
        }
        const Eigen::Vector3d base = xx > 0 ? Eigen::Vector3d((xy / xx).cwiseMax(0.0).cwiseMin(1.0))
                                            : Eigen::Vector3d::Zero();
        double sq = 0;
        for (size_t k = 0; k < hemisphere.size(); ++k) {
          sq += (base * diffuse[k] + Eigen::Vector3d::Constant(specular[k]) - target[k])
                    .squaredNorm();
        }
        const double total = yy.sum();
        Eigen::Map<Eigen::Vector3f> base_out(&out.base_color.pixels[i * 3]);
        base_out = base.cast<float>();
        out.roughness.pixels[i] = float(lobe.roughness);
        out.strength.pixels[i] = float(lobe.strength);
        out.error.pixels[i] = total > 0 ? float(std::sqrt(sq / total)) : 0.0f;
        out.converted[i] = 1;
      }
    }
  });

  std::vector<float> errors;
  for (size_t i = 0; i < src.num_pixels(); ++i) {
    if (out.converted[i]) errors.push_back(out.error.pixels[i]);
  }
  out.pixels = int(errors.size());
  if (!errors.empty()) {
    std::sort(errors.begin(), errors.end());
    out.median_error = errors[errors.size() / 2];
    out.p95_error = errors[size_t(0.95 * double(errors.size() - 1))];
    out.max_error = errors.back();
  }
  return out;
}

}  // namespace ls::relight
