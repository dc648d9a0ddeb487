#include "relight/fit/basis_materials.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <mutex>
#include <numeric>
#include <opencv2/core.hpp>
#include <span>
#include <utility>
#include <vector>

#include "relight/fit/material_pool.h"
#include "relight/fit/pixel_solver.h"
#include "relight/fit/profiled_fit.h"

namespace ls::relight {
namespace {

using materials::Cluster;
using materials::colour_distance;
using materials::grid_roughness;
using materials::kRoughnessGrid;
using materials::material_parameters;
using materials::MaterialFit;
using materials::MaterialFitter;
using materials::PoolPixel;
using materials::scale_to;
using materials::Scaled;
using materials::shape_of;
using profiled::LinearSums;
using profiled::PixelTerms;

constexpr int kPoolPixels = 96;             // Per over-segmented cluster, spread over its pixels.
constexpr int kMinClusterPixels = 8;        // Smaller clusters are left to step 4.
constexpr size_t kClusteredPixels = 16384;  // At most about this many pixels are clustered.
// Two albedos have the same colour when their chromaticities (the albedo over its sum) lie within
// this of each other: a pixel's own fit is of its material when it has the material's model and
// colour, and a blend explains a pixel only in the colour the pixel's own fit found (a scalar
// weight cannot change a material's colour; a blend of two can, along the line between them).
// 0.03 is 9% of a grey's chromaticity (1/3), several times its noise on well-exposed pixels.
constexpr double kSameColour = 0.03;

// Pixels whose own fit leaves a reduced chi^2 above this many times the median are not clustered
// (edges, cast shadows' penumbrae): they would make materials of their own.
constexpr double kClusteredResidualFactor = 4;

// The clustering features of a fitted pixel: log albedo, sigma over its range, sqrt(k_s).
std::array<float, 5> features_of(const float* m) {
  std::array<float, 5> f;
  for (int c = 0; c < 3; ++c) f[size_t(c)] = std::log(m[kMapAlbedoR + c] + 0.01f);
  f[3] = 2 * m[kMapSigma] / float(0.5 * pixel::kPi);
  f[4] = 2 * std::sqrt(std::max(0.0f, m[kMapKs]));
  return f;
}

// Step 1: the pixels to cluster, by cluster, and the scene's dispersion (MaterialFit).
struct Segments {
  std::vector<std::vector<int>> clusters;
  double dispersion = 1;
};
Segments over_segment(const ModelMaps& maps, int max_clusters) {
  const Image& image = maps.maps;
  std::vector<float> residuals;
  for (size_t i = 0; i < image.num_pixels(); ++i) {
    const float* m = &image.pixels[i * image.channels];
    if (m[kMapModel] != 0 && m[kMapFlags] == 0) residuals.push_back(m[kMapResidual]);
  }
  if (residuals.empty()) return {};
  std::nth_element(residuals.begin(), residuals.begin() + residuals.size() / 2, residuals.end());
  Segments out;
  out.dispersion = std::max(1.0, double(residuals[residuals.size() / 2]));
  const float cutoff = std::max(2.0f, float(kClusteredResidualFactor * out.dispersion));
  std::vector<int> pixels;
  cv::Mat features(0, 5, CV_32F);
  // Every stride-th pixel: the clusters only seed the materials (step 4 assigns every pixel).
  const size_t stride = std::max<size_t>(1, residuals.size() / kClusteredPixels);
  for (size_t i = 0; i < image.num_pixels(); i += stride) {
    const float* m = &image.pixels[i * image.channels];
    if (m[kMapModel] == 0 || m[kMapFlags] != 0 || m[kMapResidual] > cutoff) continue;
    const std::array<float, 5> f = features_of(m);
    features.push_back(cv::Mat(1, 5, CV_32F, const_cast<float*>(f.data())));
    pixels.push_back(int(i));
  }
  const int k = std::min(max_clusters, int(pixels.size()) / (4 * kMinClusterPixels));
  if (k < 1) return {};
  cv::Mat labels;
  cv::theRNG().state = 0x6c696768747374;  // k-means++ seeds: the same clusters every run.
  cv::kmeans(features, k, labels,
             cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-4), 1,
             cv::KMEANS_PP_CENTERS);
  std::vector<std::vector<int>> clusters(static_cast<size_t>(k));
  for (size_t j = 0; j < pixels.size(); ++j) {
    clusters[size_t(labels.at<int>(int(j)))].push_back(pixels[j]);
  }
  std::erase_if(clusters, [](const std::vector<int>& c) { return c.size() < kMinClusterPixels; });
  out.clusters = std::move(clusters);
  return out;
}

// A pixel's samples as fit_models gathers them, and its view direction.
class PixelGatherer {
 public:
  // header: the field's (or its bands') lights and view.
  PixelGatherer(const capture::ReflectanceField& header, const FitOptions& options)
      : width_(header.width()), options_(options), valid_(capture::valid_lights(header)) {}
  // The usable samples of pixel (x, y) of a band (y counted in the band) (thread-local storage,
  // valid until this thread's next call); with `shadowed`: the directions of the lights left out
  // as shadowed.
  std::span<const pixel::Sample> gather(const capture::ReflectanceField& band, int x, int y,
                                        std::vector<Eigen::Vector3d>* shadowed = nullptr) const {
    thread_local std::vector<pixel::Sample> samples;
    samples.resize(valid_.index.size());
    const int count =
        pixel::gather_samples(band, valid_, options_.normals, x, y, samples.data(), shadowed).count;
    return {samples.data(), size_t(count)};
  }
  // The view direction at pixel (x, y) of the frame.
  Eigen::Vector3d view(int x, int y) const {
    return pixel::view_dir_at(options_.view_dir_per_pixel, size_t(y) * width_ + x);
  }

 private:
  int width_;
  const FitOptions& options_;
  capture::ValidLights valid_;
};

Eigen::Vector3d fitted_normal(const float* m) {
  return Eigen::Vector3d(m[kMapNormalX], m[kMapNormalY], m[kMapNormalZ]).normalized();
}

// Steps 2 and 3: the scene's materials from its clusters, largest first.
std::vector<Material> merge_materials(const std::vector<PoolPixel>& pool,
                                      std::vector<Cluster> clusters, const FitOptions& options,
                                      double log_n, double dispersion) {
  const MaterialFitter fitter(pool, options, log_n, dispersion);
  tbb::parallel_for(size_t(0), clusters.size(), [&](size_t i) {
    clusters[i].fit =
        fitter.fit(clusters[i].members, {FitModel::kOrenNayar, FitModel::kLambertTorranceSparrow});
  });
  std::erase_if(clusters, [](const Cluster& c) { return !std::isfinite(c.fit.bic); });
  // Merged fits by pair of cluster positions, recomputed only for pairs with a new cluster.
  std::map<std::pair<size_t, size_t>, MaterialFit> merged;
  while (clusters.size() > 1) {
    std::vector<std::pair<size_t, size_t>> missing;
    for (size_t i = 0; i < clusters.size(); ++i) {
      for (size_t j = i + 1; j < clusters.size(); ++j) {
        // A weight scales a material, it cannot change its colour: materials further apart in
        // colour than a blend may be from a pixel's own (three times kSameColour) stay apart.
        const bool close = colour_distance(clusters[i].fit.material.albedo,
                                           clusters[j].fit.material.albedo) <= 3 * kSameColour;
        if (close && !merged.count({i, j})) missing.emplace_back(i, j);
      }
    }
    std::vector<MaterialFit> fits(missing.size());
    tbb::parallel_for(size_t(0), missing.size(), [&](size_t p) {
      const Cluster& a = clusters[missing[p].first];
      const Cluster& b = clusters[missing[p].second];
      std::vector<int> members = a.members;
      members.insert(members.end(), b.members.begin(), b.members.end());
      fits[p] = fitter.fit(members, {a.fit.material.model, b.fit.material.model});
    });
    for (size_t p = 0; p < missing.size(); ++p) merged[missing[p]] = fits[p];
    // The typical pixel's BIC gain: the merge's chi^2 per pixel against the parameters saved.
    double best_gain = 0;
    std::pair<size_t, size_t> best{0, 0};
    for (const auto& [pair, fit] : merged) {
      const MaterialFit& a = clusters[pair.first].fit;
      const MaterialFit& b = clusters[pair.second].fit;
      const double gain =
          (a.chi2 + b.chi2 - fit.chi2) / fit.pixels +
          (material_parameters(a.material.model) + material_parameters(b.material.model) -
           material_parameters(fit.material.model)) *
              log_n;
      if (gain > best_gain) best_gain = gain, best = pair;
    }
    if (best_gain <= 0) break;
    Cluster& into = clusters[best.first];
    const Cluster& from = clusters[best.second];
    into.members.insert(into.members.end(), from.members.begin(), from.members.end());
    into.fit = merged[best];
    clusters.erase(clusters.begin() + std::ptrdiff_t(best.second));
    // Positions after the removed cluster shift down; every pair with the merged one is stale.
    std::map<std::pair<size_t, size_t>, MaterialFit> kept;
    for (auto& [pair, fit] : merged) {
      auto [i, j] = pair;
      if (i == best.first || j == best.first || i == best.second || j == best.second) continue;
      kept[{i > best.second ? i - 1 : i, j > best.second ? j - 1 : j}] = std::move(fit);
    }
    merged = std::move(kept);
  }
  std::sort(clusters.begin(), clusters.end(),
            [](const Cluster& a, const Cluster& b) { return a.fit.pixels > b.fit.pixels; });
  // The roughness refined; a refit that fails keeps the merge's material.
  std::vector<Material> materials(clusters.size());
  tbb::parallel_for(size_t(0), clusters.size(), [&](size_t k) {
    const MaterialFit precise =
        fitter.fit(clusters[k].members, {clusters[k].fit.material.model}, /*precise=*/true);
    materials[k] = std::isfinite(precise.bic) ? precise.material : clusters[k].fit.material;
  });
  return materials;
}

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
        predicted += pixel::kLuma[c] * scale * prediction[3 * size_t(i) + size_t(c)];
        measured += pixel::kLuma[c] * terms.value(i, c);
        variance += pixel::kLuma[c] * pixel::kLuma[c] / terms.weight(i, c);
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

bool same_colour(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return colour_distance(a, b) <= kSameColour;
}

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

// Step 5: basis materials of one model and shape whose pixels tile one region are one scene
// material with an albedo texture (a checker, a print): each shares more of its boundary with the
// other than with any other material, and at least this part of it. An object on a backdrop
// shares a small part of the backdrop's boundary; two objects that touch, a small part of each's.
// (The demo's checker: 0.6 each, the next largest share of either 0.17.)
constexpr double kTextureBoundaryShare = 1.0 / 3;
constexpr double kSameShape = 0.1;  // Largest relative difference of sigma, k_s and roughness.

bool same_shape(const Material& a, const Material& b) {
  const auto close = [](double u, double v) {
    return std::abs(u - v) <= kSameShape * std::max(std::abs(u), std::abs(v));
  };
  return a.model == b.model && close(a.sigma, b.sigma) && close(a.ks, b.ks) &&
         close(a.roughness, b.roughness);
}

}  // namespace

int group_scene_materials(const Image& image, std::vector<Material>& materials) {
  const size_t n = materials.size();
  std::vector<std::vector<long>> shared(n, std::vector<long>(n, 0));
  std::vector<long> boundary(n, 0);  // Neighbour pairs (4-connected) with another label.
  const auto count = [&](int a, int b) {
    if (a == b) return;
    if (a > 0) ++boundary[size_t(a - 1)];
    if (b > 0) ++boundary[size_t(b - 1)];
    if (a > 0 && b > 0)
      ++shared[size_t(a - 1)][size_t(b - 1)], ++shared[size_t(b - 1)][size_t(a - 1)];
  };
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const int a = int(image.at(x, y, kMapMaterial));
      if (x + 1 < image.width) count(a, int(image.at(x + 1, y, kMapMaterial)));
      if (y + 1 < image.height) count(a, int(image.at(x, y + 1, kMapMaterial)));
    }
  }
  std::vector<size_t> root(n);
  std::iota(root.begin(), root.end(), size_t(0));
  const auto find = [&](size_t k) {
    while (root[k] != k) k = root[k] = root[root[k]];
    return k;
  };
  std::vector<size_t> closest(n);  // The material sharing most of each one's boundary.
  for (size_t a = 0; a < n; ++a) {
    closest[a] = size_t(std::max_element(shared[a].begin(), shared[a].end()) - shared[a].begin());
  }
  for (size_t a = 0; a < n; ++a) {
    const size_t b = closest[a];
    const double s = double(shared[a][b]);
    if (a < b && closest[b] == a && s > 0 && same_shape(materials[a], materials[b]) &&
        s >= kTextureBoundaryShare * double(boundary[a]) &&
        s >= kTextureBoundaryShare * double(boundary[b])) {
      root[find(b)] = find(a);
    }
  }
  std::vector<int> id(n, 0);
  int scene_materials = 0;
  for (size_t k = 0; k < n; ++k) {
    int& group = id[find(k)];
    if (group == 0) group = ++scene_materials;
    materials[k].scene_material = group;
  }
  return scene_materials;
}

namespace {

// Step 4 over one band: each pixel's blend of materials written into maps (rows of the frame),
// the summary's counts and the materials' pixels updated under `mutex`.
void assign_band(const capture::ReflectanceField& band, const PixelGatherer& gather,
                 const NormalMap& normals, const std::vector<Material>& materials,
                 double dispersion, const FitOptions& options, ModelMaps& maps, std::mutex& mutex) {
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
        float* m = &image.at(x, y, 0);
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
          const Eigen::Vector3d n0 = pixel::normal_at(normals, x, y);
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

BasisMaterials find_basis_materials(const capture::ReflectanceField& header,
                                    const FieldBands& bands, const ModelMaps& maps,
                                    const FitOptions& options) {
  const Image& image = maps.maps;
  const int width = image.width;
  const Segments segments = over_segment(maps, options.max_materials);
  const std::vector<std::vector<int>>& clusters = segments.clusters;
  if (clusters.empty()) return {};
  const PixelGatherer gather(header, options);
  // Each cluster's pool: up to kPoolPixels of its pixels, evenly spread; each pool pixel stands
  // for `stride` of them.
  std::vector<PoolPixel> pool;
  std::vector<int> pool_image_pixel;
  std::vector<Cluster> pooled(clusters.size());
  for (size_t k = 0; k < clusters.size(); ++k) {
    const size_t stride = (clusters[k].size() + kPoolPixels - 1) / kPoolPixels;
    for (size_t j = 0; j < clusters[k].size(); j += stride) {
      pooled[k].members.push_back(int(pool.size()));
      pool.emplace_back().scale = double(stride);
      pool_image_pixel.push_back(clusters[k][j]);
    }
  }
  // Band by band, the pool pixels in it.
  bands([&](const capture::ReflectanceField& band) {
    const int y0 = band.first_row(), y1 = y0 + band.height();
    std::vector<size_t> here;
    for (size_t p = 0; p < pool.size(); ++p) {
      const int y = pool_image_pixel[p] / width;
      if (y >= y0 && y < y1) here.push_back(p);
    }
    tbb::parallel_for(size_t(0), here.size(), [&](size_t j) {
      const size_t p = here[j];
      const int i = pool_image_pixel[p], x = i % width, y = i / width;
      PoolPixel& pixel = pool[p];
      const float* m = &image.pixels[size_t(i) * image.channels];
      pixel.own = FitModel(int(m[kMapModel]));
      const std::span<const pixel::Sample> samples = gather.gather(band, x, y - y0);
      if (samples.empty()) pixel.scale = 0;
      pixel.terms.reset(samples.data(), int(samples.size()), fitted_normal(m), gather.view(x, y));
      for (int g = 0; g < kRoughnessGrid; ++g) {
        pixel.lobe_grid[size_t(g)] =
            pixel.terms.sums(FitModel::kLambertTorranceSparrow, grid_roughness(g));
      }
    });
  });
  double residuals = 0, pixels = 0;
  for (const PoolPixel& p : pool) residuals += p.scale * 3 * p.terms.count(), pixels += p.scale;
  return {merge_materials(pool, std::move(pooled), options,
                          std::log(std::max(residuals / pixels, 2.0)), segments.dispersion),
          segments.dispersion};
}

void assign_basis_materials(const capture::ReflectanceField& header,
                            const capture::ReflectanceField& band, const NormalMap& normals,
                            const BasisMaterials& basis, const FitOptions& options,
                            ModelMaps& maps) {
  std::mutex mutex;
  assign_band(band, PixelGatherer(header, options), normals, basis.materials, basis.dispersion,
              options, maps, mutex);
  measure_fit_shadows(band, options, /*maps_first_row=*/0, maps);  // Of the models they have now.
}

void fit_basis_materials(const capture::ReflectanceField& header, const FieldBands& bands,
                         const NormalMap& normals, const FitOptions& options, ModelMaps& maps) {
  const BasisMaterials basis = find_basis_materials(header, bands, maps, options);
  if (basis.materials.empty()) return;
  maps.materials = basis.materials;
  maps.summary.materials = int(basis.materials.size());
  bands([&](const capture::ReflectanceField& band) {
    assign_basis_materials(header, band, normals, basis, options, maps);
  });
  maps.summary.scene_materials = group_scene_materials(maps.maps, maps.materials);
}

void fit_basis_materials(const capture::ReflectanceField& field, const NormalMap& normals,
                         const FitOptions& options, ModelMaps& maps) {
  fit_basis_materials(
      field, [&](const BandVisitor& visit) { visit(field); }, normals, options, maps);
}

}  // namespace ls::relight
