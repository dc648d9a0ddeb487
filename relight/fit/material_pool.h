#pragma once
// The pooled fit of basis materials (relight/fit/basis_materials.h), internal to relight_fit: the
// pool pixels a material is fitted on, and the alternating fit of a material and its pixels'
// weights over them. Conventions as relight/fit/profiled_fit.h.
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <span>
#include <vector>

#include "relight/fit/fit.h"
#include "relight/fit/pixel_solver.h"
#include "relight/fit/profiled_fit.h"

namespace ls::relight::materials {

using profiled::LinearSums;
using profiled::PixelTerms;

constexpr int kRoughnessGrid = 32;    // Log-spaced over [0.02, 1]: no resolvable bound pooled.
constexpr int kMinShapingPixels = 8;  // Fewer pixels of a material's own model: shape on all.

// The distance between two albedos' chromaticities (each albedo over its sum).
inline double colour_distance(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  if (!(a.sum() > 0 && b.sum() > 0)) return HUGE_VAL;
  return (a / a.sum() - b / b.sum()).norm();
}

inline double shape_of(const Material& m) {
  if (m.model == FitModel::kOrenNayar) return m.sigma;
  if (m.model == FitModel::kLambertTorranceSparrow) return m.roughness;
  return 0;
}

// Two albedos have the same colour when their chromaticities (the albedo over its sum) lie within
// this of each other: a pixel's own fit is of its material when it has the material's model and
// colour, and a blend explains a pixel only in the colour the pixel's own fit found (a scalar
// weight cannot change a material's colour; a blend of two can, along the line between them).
// 0.03 is 9% of a grey's chromaticity (1/3), several times its noise on well-exposed pixels.
constexpr double kSameColour = 0.03;

inline bool same_colour(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return colour_distance(a, b) <= kSameColour;
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

inline Eigen::Vector3d fitted_normal(const float* m) {
  return Eigen::Vector3d(m[kMapNormalX], m[kMapNormalY], m[kMapNormalZ]).normalized();
}

// A material's parameters: albedo r g b, plus sigma, or plus k_s and the roughness.
inline int material_parameters(FitModel model) {
  return model == FitModel::kLambert ? 3 : model == FitModel::kOrenNayar ? 4 : 5;
}

// The weight w >= 0 that best scales a material to a pixel, and chi^2 there, from the pixel's sums
// at the material's shape.
struct Scaled {
  double weight = 0, chi2 = 0;
};
inline Scaled scale_to(const LinearSums<double>& s, const Material& m) {
  double num = 0, den = 0, vv = 0;
  for (int c = 0; c < 3; ++c) {
    const double a = m.albedo(c);
    num += a * s.av[c] + m.ks * s.bv[c];
    den += a * a * s.aa[c] + 2 * a * m.ks * s.ab[c] + m.ks * m.ks * s.bb[c];
    vv += s.vv[c];
  }
  const double w = den > 0 && num > 0 ? num / den : 0;
  return {w, std::max(0.0, vv - 2 * w * num + w * w * den)};
}

// The roughness grid of the pooled Torrance-Sparrow search: log-spaced over [0.02, 1], 12% steps.
inline double grid_roughness(int k) {
  const double lo = std::log(pixel::kMinRoughness);
  return std::exp(lo - lo * k / (kRoughnessGrid - 1));
}

// A pixel of a material's pool: its terms at its fitted normal, its Lambert + Torrance-Sparrow
// sums at every grid roughness (computed once: a merge tries every pair of materials), and how
// many of the scene's pixels it stands for.
struct PoolPixel {
  PixelTerms terms;
  std::array<LinearSums<double>, kRoughnessGrid> lobe_grid;
  double scale = 1;
  FitModel own = FitModel::kNone;  // The model its own fit chose (whose normal it has).
};

// Every choice about materials (a material's model, whether two materials are one) is made by
// the BIC of the material's typical pixel: its mean chi^2 per pixel plus the material's
// parameters times ln of a pixel's residual count. The scene's BIC over all residuals would let
// millions of residuals buy any parameter that absorbs an error common to the material's pixels
// (an LED's calibration, the normals' bias): a material is kept apart, or given a lobe or sigma,
// only where its typical pixel's own evidence supports it. chi^2 is divided by the scene's
// dispersion, the median reduced chi^2 of the pixels' own fits when above 1 (quasi-likelihood):
// where the noise model is too optimistic (an 8-bit JPEG set with no measured noise) or no model
// is exact, chi^2 differences are that many times larger than the BIC's penalties assume.
struct MaterialFit {
  Material material;
  double chi2 = HUGE_VAL;  // Scaled to the scene, divided by the dispersion.
  double pixels = 0;       // Scene pixels (sum of the pool pixels' scales).
  double bic = HUGE_VAL;   // chi2 / pixels + parameters * ln(residuals per pixel).
};

struct Cluster {
  std::vector<int> members;  // Into the pool.
  MaterialFit fit;
};

class MaterialFitter {
 public:
  // log_n: ln of a pixel's residual count; dispersion: as above.
  MaterialFitter(const std::vector<PoolPixel>& pool, const FitOptions& options, double log_n,
                 double dispersion)
      : pool_(pool), options_(options), log_n_(log_n), dispersion_(dispersion) {}

  // The best material by BIC over Lambert and `models` (the union of those merged). Not precise:
  // the roughness from the grid and one parabolic step (merges try every pair); precise: refined
  // by golden section too.
  MaterialFit fit(const std::vector<int>& members, std::initializer_list<FitModel> models,
                  bool precise = false) const;

 private:
  MaterialFit fit_model(const std::vector<int>& members, FitModel model, bool precise) const;
  template <class SumsOf>
  double pooled_chi2(const std::vector<int>& members, const std::vector<double>& w,
                     const SumsOf& sums_of, Material* m) const;
  double pooled_chi2_at(const std::vector<int>& members, const std::vector<double>& w, double shape,
                        Material* m) const;
  void search_shape(const std::vector<int>& members, const std::vector<double>& w, bool precise,
                    Material* m) const;

  const std::vector<PoolPixel>& pool_;
  const FitOptions& options_;
  double log_n_, dispersion_;
};

}  // namespace ls::relight::materials
