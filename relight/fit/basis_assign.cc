// Step 4 of basis materials (relight/fit/basis_materials.h): each pixel as a blend of one or two
// materials, its weights fitted on the samples the blend leaves lit, and its FitShadows measured
// again for the models it has now.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <span>
#include <vector>

#include "lightstage/image.h"
#include "relight/fit/basis_materials.h"
#include "relight/fit/material_pool.h"
#include "relight/fit/pixel_solver.h"
#include "relight/fit/profiled_fit.h"

namespace ls::relight {
namespace {

using materials::fitted_normal;
using materials::PixelGatherer;
using materials::same_colour;
using materials::scale_to;
using materials::Scaled;
using materials::shape_of;
using profiled::PixelTerms;

// A pixel's reflectance as one or two materials (step 4).
struct Blend {
  int material[2] = {-1, -1};  // 0-based; -1 = none.
  double weight[2] = {0, 0};
  double chi2 = HUGE_VAL;
  int weights() const { return (material[0] >= 0) + (material[1] >= 0); }
};

Blend blend_of(const PixelTerms& terms, const std::vector<Material>& materials, double log_n) {
  Blend best;
  thread_local std::vector<double> chi2;
  chi2.assign(materials.size(), HUGE_VAL);
  for (size_t k = 0; k < materials.size(); ++k) {
    const Scaled s = scale_to(terms.sums(materials[k].model, shape_of(materials[k])), materials[k]);
    chi2[k] = s.chi2;
    if (s.weight > 0 && s.chi2 < best.chi2) {
      best = Blend{};
      best.material[0] = int(k);
      best.weight[0] = s.weight;
      best.chi2 = s.chi2;
    }
  }
  if (best.material[0] < 0) return best;
  // The best second material of the same model, by its chi^2 alone.
  const Material& first = materials[size_t(best.material[0])];
  int second = -1;
  for (size_t k = 0; k < materials.size(); ++k) {
    if (int(k) != best.material[0] && materials[k].model == first.model &&
        (second < 0 || chi2[k] < chi2[size_t(second)])) {
      second = int(k);
    }
  }
  if (second < 0) return best;
  // Two non-negative weights: the 2x2 normal equations, kept only when both come out positive.
  thread_local std::vector<double> p1, p2;
  const int n = terms.count();
  p1.resize(3 * size_t(n));
  p2.resize(3 * size_t(n));
  const Material& other = materials[size_t(second)];
  terms.predict(first.model, shape_of(first), first.albedo, first.ks, p1.data());
  terms.predict(other.model, shape_of(other), other.albedo, other.ks, p2.data());
  double g11 = 0, g12 = 0, g22 = 0, r1 = 0, r2 = 0, vv = 0;
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      const double w = terms.weight(i, c), v = terms.value(i, c);
      const size_t k = 3 * size_t(i) + size_t(c);
      const double a = p1[k], b = p2[k];
      g11 += w * a * a, g12 += w * a * b, g22 += w * b * b;
      r1 += w * a * v, r2 += w * b * v, vv += w * v * v;
    }
  }
  const double det = g11 * g22 - g12 * g12;
  if (!(det > 0)) return best;
  const double w1 = (g22 * r1 - g12 * r2) / det, w2 = (g11 * r2 - g12 * r1) / det;
  if (!(w1 > 0 && w2 > 0)) return best;
  const double pair_chi2 = std::max(
      0.0, vv - 2 * (w1 * r1 + w2 * r2) + w1 * w1 * g11 + 2 * w1 * w2 * g12 + w2 * w2 * g22);
  if (pair_chi2 + log_n >= best.chi2) return best;  // BIC: one more weight.
  Blend pair;
  pair.material[0] = w1 >= w2 ? best.material[0] : second;
  pair.material[1] = w1 >= w2 ? second : best.material[0];
  pair.weight[0] = std::max(w1, w2);
  pair.weight[1] = std::min(w1, w2);
  pair.chi2 = pair_chi2;
  return pair;
}

// The fraction of a lobe of this roughness at normal n that the pixel's samples saw lit: the sum
// of exp(-tan^2(theta_h) / m^2) over the samples, over its sum over the samples and the lights
// left out as shadowed. 1 where no light falls within the lobe (nothing says it is shadowed).
double lobe_visibility(const PixelTerms& terms, const std::vector<Eigen::Vector3d>& shadowed,
                       const Eigen::Vector3d& n, const Eigen::Vector3d& view, double roughness) {
  const double lit = terms.lobe_weight(roughness), inv_m2 = 1 / (roughness * roughness);
  double dark = 0;
  for (const Eigen::Vector3d& l : shadowed) {
    if (n.dot(l) <= 0) continue;  // Below the surface: no lobe there.
    const double cos_h = n.dot((l + view).normalized());
    if (cos_h <= 0) continue;
    const double cos_h2 = cos_h * cos_h;
    dark += std::exp(-std::min(40.0, (1 - cos_h2) / cos_h2 * inv_m2));
  }
  return lit + dark > 1e-6 ? lit / (lit + dark) : 1.0;
}

// The factor that fits a blend's prediction to the samples it leaves lit. A sample clearly below
// the prediction (by FitShadows::kShadowSigmas of its noise) is in partial shadow: it tells of the
// light that reached the pixel, not of its reflectance, and the render takes that light away
// again (ModelMaps::shadows). Least squares over every sample would dim the whole pixel for it.
// A few rounds: a brighter blend finds more of its penumbra.
double lit_scale(const PixelTerms& terms, const Blend& blend,
                 const std::vector<Material>& materials) {
  thread_local std::vector<double> prediction, one;
  const int n = terms.count();
  prediction.assign(3 * size_t(n), 0);
  one.resize(3 * size_t(n));
  for (int j = 0; j < blend.weights(); ++j) {
    const Material& mat = materials[size_t(blend.material[j])];
    terms.predict(mat.model, shape_of(mat), mat.albedo, mat.ks, one.data());
    for (size_t k = 0; k < one.size(); ++k) prediction[k] += blend.weight[j] * one[k];
  }
  double scale = 1;
  for (int round = 0; round < 3; ++round) {
    double pv = 0, pp = 0;
    for (int i = 0; i < n; ++i) {
      double predicted = 0, measured = 0, variance = 0;
      for (int c = 0; c < 3; ++c) {
        predicted += kLuminanceWeights[c] * scale * prediction[3 * size_t(i) + size_t(c)];
        measured += kLuminanceWeights[c] * terms.value(i, c);
        variance += kLuminanceWeights[c] * kLuminanceWeights[c] / terms.weight(i, c);
      }
      if (predicted - measured > FitShadows::kShadowSigmas * std::sqrt(variance)) continue;
      for (int c = 0; c < 3; ++c) {
        const double p = prediction[3 * size_t(i) + size_t(c)], w = terms.weight(i, c);
        pv += w * p * terms.value(i, c);
        pp += w * p * p;
      }
    }
    if (!(pp > 0 && pv > 0)) return scale;
    const double next = pv / pp;
    if (std::abs(next - scale) < 1e-3 * scale) return next;
    scale = next;
  }
  return scale;
}

// Below this lit share of its lobe a pixel is flagged kLobeShadowed.
constexpr double kLobeLitShare = 0.99;

// A material explains a pixel unless it leaves more than this many times the residual variance
// (reduced chi^2) of the pixel's own fit: a texture the weights cannot follow, a material the
// clustering missed. Not the BIC: the pixel's own fit wins the BIC wherever a lobe or sigma absorbs
// an error common to its neighbours (a penumbra, light from a neighbouring object), the speckle
// the materials are there to remove.
constexpr double kUnexplainedResidualRatio = 3;
// A pixel's own fit that leaves ten times the scene's typical residual variance (its dispersion)
// explains the pixel no better than its material (a penumbra, a pixel straddling an occluding
// edge): its extra parameters fit the misfit, and its colour is not the surface's.
constexpr double kUnexplainedOwnDispersions = 10;

// Writes a blend into the map values m (normal n) unless the blend leaves the pixel unexplained
// (kUnexplainedResidualRatio: also where the pixel's own fit is poor, as on a silhouette, whose
// mixed colour its own fit renders better) or in another colour while its own fit explains it;
// returns whether the pixel now belongs to the blend's materials. A pixel whose own fit is of its
// main material (same_colour) and explains it better by BIC keeps its own parameters, flagged
// kOwnParameters, whatever the blend leaves: a highlight seen across a silhouette pixel's
// footprint is wider than the material's. The model is the material's all the same (no speckle),
// and the material stands in only where the pixel's own data are silent.
bool write_blend(const Blend& blend, const Eigen::Vector3d& n, int residuals,
                 const std::vector<Material>& materials, bool refine_normal, double dispersion,
                 float* m) {
  // The blend's parameters: weighted sums; the two materials share a model, and their shapes
  // are averaged by weight.
  const Material& main = materials[size_t(blend.material[0])];
  Material mix;
  double total = 0;
  for (int j = 0; j < blend.weights(); ++j) {
    const Material& mat = materials[size_t(blend.material[j])];
    const double w = blend.weight[j];
    mix.albedo += w * mat.albedo;
    mix.ks += w * mat.ks;
    mix.sigma += w * mat.sigma;
    mix.roughness += w * mat.roughness;
    total += w;
  }
  const FitModel own = FitModel(int(m[kMapModel]));
  const Eigen::Vector3d own_albedo(m[kMapAlbedoR], m[kMapAlbedoG], m[kMapAlbedoB]);
  const bool own_is_main = own == main.model && same_colour(own_albedo, main.albedo);
  const int k_own = model_parameters(own, refine_normal);
  const int k_blend = blend.weights() + (refine_normal ? 2 : 0);
  const double reduced_chi2 = blend.chi2 / std::max(1, residuals - k_blend);
  const double log_n = std::log(double(residuals));
  const double own_bic = double(m[kMapResidual]) * std::max(1, residuals - k_own) + k_own * log_n;
  const double blend_bic = blend.chi2 + k_blend * log_n;
  // Another colour counts against the blend only where the data tell it apart (the blend loses
  // by BIC: a dark pixel's own colour is mostly its noise).
  const bool own_explains = m[kMapResidual] <= kUnexplainedOwnDispersions * dispersion;
  const bool other_colour = blend_bic > own_bic && !same_colour(mix.albedo, own_albedo);
  const bool explained = reduced_chi2 <= kUnexplainedResidualRatio * m[kMapResidual] &&
                         (!own_explains || !other_colour);
  if (!explained && !own_is_main) return false;
  for (int j = 0; j < 2; ++j) {
    m[kMapMaterial + 2 * j] = float(blend.material[j] + 1);
    m[kMapMaterialWeight + 2 * j] = float(blend.weight[j]);
  }
  if (own_is_main && own_bic < blend_bic) {
    m[kMapFlags] = float(int(m[kMapFlags]) | kOwnParameters);
    return true;
  }
  for (int c = 0; c < 3; ++c) {
    m[kMapNormalX + c] = float(n(c));
    m[kMapAlbedoR + c] = float(mix.albedo(c));
  }
  m[kMapSigma] = float(mix.sigma / total);
  m[kMapKs] = float(mix.ks);
  m[kMapRoughness] = float(mix.roughness / total);
  m[kMapModel] = float(int(main.model));
  // The BIC weight of the blend against the pixel's own fit.
  m[kMapConfidence] = float(1 / (1 + std::exp(-0.5 * (own_bic - blend_bic))));
  m[kMapResidual] = float(reduced_chi2);
  m[kMapFlags] = float(int(m[kMapFlags]) & ~kFitNotConverged);  // Closed form: converged.
  return true;
}

// Step 4 over one band: each pixel's blend of materials written into maps (rows of the frame),
// the summary's counts and the materials' pixels updated under `mutex`.
void assign_band(const capture::ReflectanceField& band, const PixelGatherer& gather,
                 const NormalMap& normals, const std::vector<Material>& materials,
                 double dispersion, const FitOptions& options, int maps_first_row, ModelMaps& maps,
                 std::mutex& mutex) {
  Image& image = maps.maps;
  const int y0 = band.first_row();
  tbb::parallel_for(tbb::blocked_range<int>(0, band.height()), [&](const auto& rows) {
    thread_local PixelTerms at_fitted, at_n0;
    thread_local std::vector<Eigen::Vector3d> shadowed;
    FitSummary local;
    std::vector<int> main_of(materials.size(), 0);
    for (int band_y = rows.begin(); band_y < rows.end(); ++band_y) {
      const int y = y0 + band_y;
      for (int x = 0; x < image.width; ++x) {
        float* m = &image.at(x, y - maps_first_row, 0);
        const FitModel own = FitModel(int(m[kMapModel]));
        if (own == FitModel::kNone) continue;
        const std::span<const pixel::Sample> samples = gather.gather(band, x, band_y, &shadowed);
        if (samples.empty()) continue;
        const Eigen::Vector3d view = gather.view(x, y);
        Eigen::Vector3d n = fitted_normal(m);
        at_fitted.reset(samples.data(), int(samples.size()), n, view);
        const PixelTerms* terms = &at_fitted;
        const double log_n = std::log(double(3 * samples.size()));
        Blend blend = blend_of(at_fitted, materials, log_n);
        if (blend.material[0] >= 0 && materials[size_t(blend.material[0])].model != own) {
          // The own fit's normal is biased toward its own model: try the photometric-stereo one.
          const Eigen::Vector3d n0 = pixel::normal_at(normals, x, y - maps_first_row);
          at_n0.reset(samples.data(), int(samples.size()), n0, view);
          const Blend blend_n0 = blend_of(at_n0, materials, log_n);
          if (blend_n0.chi2 < blend.chi2) blend = blend_n0, n = n0, terms = &at_n0;
        }
        if (blend.material[0] < 0) continue;
        const bool was_not_converged = (int(m[kMapFlags]) & kFitNotConverged) != 0;
        if (!write_blend(blend, n, 3 * int(samples.size()), materials, options.refine_normal,
                         dispersion, m)) {
          continue;
        }
        if ((int(m[kMapFlags]) & kOwnParameters) == 0) {
          const float scale = float(lit_scale(*terms, blend, materials));
          for (const MapChannel c : {kMapAlbedoR, kMapAlbedoG, kMapAlbedoB, kMapKs,
                                     kMapMaterialWeight, kMapMaterial2Weight}) {
            m[c] *= scale;
          }
        }
        if (m[kMapKs] > 0 &&
            lobe_visibility(*terms, shadowed, n, view, m[kMapRoughness]) < kLobeLitShare) {
          m[kMapFlags] = float(int(m[kMapFlags]) | kLobeShadowed);
        }
        --local.per_model[int(own)];
        ++local.per_model[int(m[kMapModel])];
        local.not_converged -= was_not_converged && (int(m[kMapFlags]) & kFitNotConverged) == 0;
        ++local.material_pixels;
        ++main_of[size_t(blend.material[0])];
      }
    }
    const std::lock_guard lock(mutex);
    maps.summary.add(local);
    for (size_t k = 0; k < materials.size(); ++k) maps.materials[k].pixels += main_of[k];
  });
}

}  // namespace

void assign_basis_materials(const capture::ReflectanceField& header,
                            const capture::ReflectanceField& band, const NormalMap& normals,
                            const BasisMaterials& basis, const FitOptions& options, ModelMaps& maps,
                            int maps_first_row) {
  std::mutex mutex;
  assign_band(band, PixelGatherer(header, options), normals, basis.materials, basis.dispersion,
              options, maps_first_row, maps, mutex);
  measure_fit_shadows(band, options, maps_first_row, maps);  // Of the models they have now.
}

}  // namespace ls::relight
