#include "relight/fit/basis_materials.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
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
using materials::fitted_normal;
using materials::grid_roughness;
using materials::kRoughnessGrid;
using materials::kSameColour;
using materials::material_parameters;
using materials::MaterialFit;
using materials::MaterialFitter;
using materials::PixelGatherer;
using materials::PoolPixel;

constexpr int kPoolPixels = 96;             // Per over-segmented cluster, spread over its pixels.
constexpr int kMinClusterPixels = 8;        // Smaller clusters are left to step 4.
constexpr size_t kClusteredPixels = 16384;  // At most about this many pixels are clustered.

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

// A fitted pixel that step 1 may cluster: its place and its own fit's maps.
struct Candidate {
  size_t pixel = 0;  // y * width + x.
  std::array<float, kMapChannelCount> maps{};
};

// Whether step 1 may cluster the pixel: its own fit has a model and no flag.
bool fitted_cleanly(const float* m) { return m[kMapModel] != 0 && m[kMapFlags] == 0; }

// A float's bits as an unsigned key in the floats' order (the median found by its bits).
uint32_t order_key(float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  return (bits & 0x80000000u) ? ~bits : bits | 0x80000000u;
}

// The cleanly fitted pixels' median residual (the element nth_element puts at n / 2) and every
// stride-th of them (the stride from their number: about kClusteredPixels), in two passes over the
// maps' bands without holding a value per pixel: a histogram of the residuals' top 16 key bits;
// then the values in the median's bucket, and the strided pixels.
struct FittedPixels {
  float median_residual = 0;
  std::vector<Candidate> strided;  // Empty: no pixel fitted cleanly.
};
FittedPixels fitted_pixels(const MapsBands& bands) {
  std::vector<size_t> histogram(size_t(1) << 16, 0);
  size_t count = 0;
  bands([&](const Image& maps, int) {
    for (size_t i = 0; i < maps.num_pixels(); ++i) {
      const float* m = &maps.pixels[i * size_t(maps.channels)];
      if (fitted_cleanly(m)) ++histogram[order_key(m[kMapResidual]) >> 16], ++count;
    }
  });
  if (count == 0) return {};
  size_t rank = count / 2, bucket = 0;
  while (rank >= histogram[bucket]) rank -= histogram[bucket++];
  std::vector<float> in_bucket;
  in_bucket.reserve(histogram[bucket]);
  FittedPixels out;
  // Every stride-th pixel: the clusters only seed the materials (step 4 assigns every pixel).
  const size_t stride = std::max<size_t>(1, count / kClusteredPixels);
  bands([&](const Image& maps, int first_row) {
    const size_t first = size_t(first_row) * size_t(maps.width);
    for (size_t i = 0; i < maps.num_pixels(); ++i) {
      const float* m = &maps.pixels[i * size_t(maps.channels)];
      if (!fitted_cleanly(m)) continue;
      if (order_key(m[kMapResidual]) >> 16 == bucket) in_bucket.push_back(m[kMapResidual]);
      if ((first + i) % stride != 0) continue;
      Candidate& pixel = out.strided.emplace_back();
      pixel.pixel = first + i;
      std::copy_n(m, kMapChannelCount, pixel.maps.begin());
    }
  });
  std::nth_element(in_bucket.begin(), in_bucket.begin() + std::ptrdiff_t(rank), in_bucket.end());
  out.median_residual = in_bucket[rank];
  return out;
}

// Step 1: the pixels to cluster, by cluster (indices into `pixels`), and the scene's dispersion
// (MaterialFit).
struct Segments {
  std::vector<Candidate> pixels;
  std::vector<std::vector<int>> clusters;
  double dispersion = 1;
};
Segments over_segment(const MapsBands& bands, int max_clusters) {
  FittedPixels fitted = fitted_pixels(bands);
  if (fitted.strided.empty()) return {};
  Segments out;
  out.dispersion = std::max(1.0, double(fitted.median_residual));
  const float cutoff = std::max(2.0f, float(kClusteredResidualFactor * out.dispersion));
  cv::Mat features(0, 5, CV_32F);
  for (Candidate& pixel : fitted.strided) {
    if (pixel.maps[kMapResidual] > cutoff) continue;
    const std::array<float, 5> f = features_of(pixel.maps.data());
    features.push_back(cv::Mat(1, 5, CV_32F, const_cast<float*>(f.data())));
    out.pixels.push_back(pixel);
  }
  const int k = std::min(max_clusters, int(out.pixels.size()) / (4 * kMinClusterPixels));
  if (k < 1) return {};
  cv::Mat labels;
  cv::theRNG().state = 0x6c696768747374;  // k-means++ seeds: the same clusters every run.
  cv::kmeans(features, k, labels,
             cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-4), 1,
             cv::KMEANS_PP_CENTERS);
  std::vector<std::vector<int>> clusters(static_cast<size_t>(k));
  for (size_t j = 0; j < out.pixels.size(); ++j) {
    clusters[size_t(labels.at<int>(int(j)))].push_back(int(j));
  }
  std::erase_if(clusters, [](const std::vector<int>& c) { return c.size() < kMinClusterPixels; });
  out.clusters = std::move(clusters);
  return out;
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

int group_scene_materials(const Image& maps, std::vector<Material>& materials) {
  return group_scene_materials(whole_maps(maps), materials);
}

int group_scene_materials(const MapsBands& bands, std::vector<Material>& materials) {
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
  std::vector<int> row_above;  // The previous band's last row, its materials.
  bands([&](const Image& band, int) {
    for (int y = 0; y < band.height; ++y) {
      for (int x = 0; x < band.width; ++x) {
        const int a = int(band.at(x, y, kMapMaterial));
        if (x + 1 < band.width) count(a, int(band.at(x + 1, y, kMapMaterial)));
        if (y > 0) count(int(band.at(x, y - 1, kMapMaterial)), a);
        if (y == 0 && !row_above.empty()) count(row_above[size_t(x)], a);
      }
    }
    row_above.resize(size_t(band.width));
    for (int x = 0; x < band.width && band.height > 0; ++x) {
      row_above[size_t(x)] = int(band.at(x, band.height - 1, kMapMaterial));
    }
  });
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

BasisMaterials find_basis_materials(const capture::ReflectanceField& header, const FieldRows& rows,
                                    const MapsBands& maps, const FitOptions& options) {
  const int width = header.width();
  const Segments segments = over_segment(maps, options.max_materials);
  const std::vector<std::vector<int>>& clusters = segments.clusters;
  if (clusters.empty()) return {};
  const PixelGatherer gather(header, options);
  // Each cluster's pool: up to kPoolPixels of its pixels, evenly spread; each pool pixel stands
  // for `stride` of them.
  std::vector<PoolPixel> pool;
  std::vector<const Candidate*> pool_pixel;
  std::vector<Cluster> pooled(clusters.size());
  for (size_t k = 0; k < clusters.size(); ++k) {
    const size_t stride = (clusters[k].size() + kPoolPixels - 1) / kPoolPixels;
    for (size_t j = 0; j < clusters[k].size(); j += stride) {
      pooled[k].members.push_back(int(pool.size()));
      pool.emplace_back().scale = double(stride);
      pool_pixel.push_back(&segments.pixels[size_t(clusters[k][j])]);
    }
  }
  // Row by row (top to bottom: a band read serves its next rows), the pool pixels in it.
  std::vector<size_t> by_row(pool.size());
  std::iota(by_row.begin(), by_row.end(), size_t(0));
  std::stable_sort(by_row.begin(), by_row.end(), [&](size_t a, size_t b) {
    return pool_pixel[a]->pixel / size_t(width) < pool_pixel[b]->pixel / size_t(width);
  });
  for (size_t first = 0; first < by_row.size();) {
    const int y = int(pool_pixel[by_row[first]]->pixel / size_t(width));
    size_t last = first;
    while (last < by_row.size() && int(pool_pixel[by_row[last]]->pixel / size_t(width)) == y) {
      ++last;
    }
    const capture::ReflectanceField& band = rows(y);
    tbb::parallel_for(first, last, [&](size_t j) {
      const size_t p = by_row[j];
      const int x = int(pool_pixel[p]->pixel % size_t(width));
      PoolPixel& pixel = pool[p];
      const float* m = pool_pixel[p]->maps.data();
      pixel.own = FitModel(int(m[kMapModel]));
      const std::span<const pixel::Sample> samples = gather.gather(band, x, y - band.first_row());
      if (samples.empty()) pixel.scale = 0;
      pixel.terms.reset(samples.data(), int(samples.size()), fitted_normal(m), gather.view(x, y));
      for (int g = 0; g < kRoughnessGrid; ++g) {
        pixel.lobe_grid[size_t(g)] =
            pixel.terms.sums(FitModel::kLambertTorranceSparrow, grid_roughness(g));
      }
    });
    first = last;
  }
  double residuals = 0, pixels = 0;
  for (const PoolPixel& p : pool) residuals += p.scale * 3 * p.terms.count(), pixels += p.scale;
  return {merge_materials(pool, std::move(pooled), options,
                          std::log(std::max(residuals / pixels, 2.0)), segments.dispersion),
          segments.dispersion};
}

void fit_basis_materials(const capture::ReflectanceField& field, const NormalMap& normals,
                         const FitOptions& options, ModelMaps& maps) {
  const BasisMaterials basis =
      find_basis_materials(field, whole_field_rows(field), whole_maps(maps.maps), options);
  if (basis.materials.empty()) return;
  maps.materials = basis.materials;
  maps.summary.materials = int(basis.materials.size());
  assign_basis_materials(field, field, normals, basis, options, maps);
  maps.summary.scene_materials = group_scene_materials(maps.maps, maps.materials);
}

}  // namespace ls::relight
