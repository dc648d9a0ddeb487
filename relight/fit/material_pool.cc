#include "relight/fit/material_pool.h"

namespace ls::relight::materials {
namespace {

constexpr int kAlternations = 3;  // Weights, then material, three times.
using profiled::kRefineSteps;
using profiled::kSigmaGrid;

}  // namespace

// The best material by BIC over Lambert and `models` (the union of those merged). Not precise:
// the roughness from the grid and one parabolic step (merges try every pair); precise: refined
// by golden section too.
MaterialFit MaterialFitter::fit(const std::vector<int>& members,
                                std::initializer_list<FitModel> models, bool precise) const {
  MaterialFit best = fit_model(members, FitModel::kLambert, precise);
  for (const FitModel model : models) {
    if (model == FitModel::kLambert) continue;
    if (model == FitModel::kOrenNayar && !options_.fit_oren_nayar) continue;
    if (model == FitModel::kLambertTorranceSparrow && !options_.fit_torrance_sparrow) continue;
    const MaterialFit f = fit_model(members, model, precise);
    if (f.bic < best.bic) best = f;
  }
  return best;
}

// Alternates the pixels' weights (closed form) and the material (albedo and k_s in closed form
// over the pooled sums, the shape searched); the mean weight is kept at 1.
MaterialFit MaterialFitter::fit_model(const std::vector<int>& members, FitModel model,
                                      bool precise) const {
  // The shape is fitted on the pixels whose own fit chose this model, when there are enough:
  // their normals were refined under it. A Lambert fit's normal on an Oren-Nayar surface is
  // tilted to mimic the flatter shading, and would bias sigma low.
  std::vector<int> shaping;
  if (model != FitModel::kLambert) {
    for (const int j : members) {
      if (pool_[size_t(j)].own == model) shaping.push_back(j);
    }
  }
  if (shaping.size() < size_t(kMinShapingPixels)) shaping = members;
  std::vector<double> w(shaping.size(), 1.0);
  Material m;
  m.model = model;
  for (int round = 0; round < kAlternations; ++round) {
    search_shape(shaping, w, precise && round == kAlternations - 1, &m);
    if (!(m.albedo.allFinite() && std::isfinite(m.ks))) return {};
    double weighted = 0, scales = 0;
    for (size_t j = 0; j < shaping.size(); ++j) {
      const PoolPixel& p = pool_[size_t(shaping[j])];
      w[j] = scale_to(p.terms.sums(model, shape_of(m)), m).weight;
      weighted += p.scale * w[j];
      scales += p.scale;
    }
    if (!(weighted > 0)) return {};
    const double mean = weighted / scales;
    m.albedo *= mean;
    m.ks *= mean;
    for (double& wj : w) wj /= mean;
  }
  if (m.ks > options_.max_specular_albedo) return {};
  double chi2 = 0, pixels = 0;
  for (const int j : members) {
    const PoolPixel& p = pool_[size_t(j)];
    chi2 += p.scale * scale_to(p.terms.sums(model, shape_of(m)), m).chi2;
    pixels += p.scale;
  }
  chi2 /= dispersion_;
  return {m, chi2, pixels, chi2 / pixels + material_parameters(model) * log_n_};
}

// The pooled least squares of the members' sums (sums_of(pool pixel), each scaled by the
// pixel's weight): fills m's albedo and k_s, returns chi^2 (infinite for a lobe above the k_s
// bound).
template <class SumsOf>
double MaterialFitter::pooled_chi2(const std::vector<int>& members, const std::vector<double>& w,
                                   const SumsOf& sums_of, Material* m) const {
  LinearSums<double> total{};
  for (size_t j = 0; j < members.size(); ++j) {
    const PoolPixel& p = pool_[size_t(members[j])];
    const LinearSums<double>& s = sums_of(p);
    const double a = p.scale * w[j], a2 = a * w[j];
    for (int c = 0; c < 3; ++c) {
      total.aa[c] += a2 * s.aa[c];
      total.ab[c] += a2 * s.ab[c];
      total.bb[c] += a2 * s.bb[c];
      total.av[c] += a * s.av[c];
      total.bv[c] += a * s.bv[c];
      total.vv[c] += p.scale * s.vv[c];
    }
  }
  const bool lobe = m->model == FitModel::kLambertTorranceSparrow;
  profiled::solve_linear(total, lobe, m->albedo.data(), &m->ks);
  if (m->ks > options_.max_specular_albedo) return HUGE_VAL;
  return profiled::chi2_of(total, m->albedo.data(), m->ks);
}
double MaterialFitter::pooled_chi2_at(const std::vector<int>& members, const std::vector<double>& w,
                                      double shape, Material* m) const {
  return pooled_chi2(
      members, w, [&](const PoolPixel& p) { return p.terms.sums(m->model, shape); }, m);
}

// Sets m's shape (sigma or roughness), albedo and k_s.
void MaterialFitter::search_shape(const std::vector<int>& members, const std::vector<double>& w,
                                  bool precise, Material* m) const {
  if (m->model == FitModel::kLambert) {
    pooled_chi2_at(members, w, 0, m);
    return;
  }
  Material scratch = *m;
  // Over t: sigma in [0, pi/2] (any sigma costs nothing per sample), or log roughness in
  // [ln 0.02, 0] (from the grid's sums, then a parabolic step).
  const bool on = m->model == FitModel::kOrenNayar;
  const int grid = on ? kSigmaGrid : kRoughnessGrid;
  const double lo = on ? 0 : std::log(pixel::kMinRoughness), hi = on ? 0.5 * pixel::kPi : 0;
  const double step = (hi - lo) / (grid - 1);
  auto to_shape = [&](double t) { return on ? t : std::exp(t); };
  auto chi2_at = [&](double t) { return pooled_chi2_at(members, w, to_shape(t), &scratch); };
  std::array<double, std::max(kSigmaGrid, kRoughnessGrid)> chi2;
  int best = 0;
  for (int k = 0; k < grid; ++k) {
    chi2[size_t(k)] =
        on ? chi2_at(lo + k * step)
           : pooled_chi2(
                 members, w, [&](const PoolPixel& p) { return p.lobe_grid[size_t(k)]; }, &scratch);
    if (chi2[size_t(k)] < chi2[size_t(best)]) best = k;
  }
  double t = lo + best * step, best_chi2 = chi2[size_t(best)];
  if (!on && best > 0 && best < grid - 1) {
    const double below = chi2[size_t(best) - 1], above = chi2[size_t(best) + 1];
    const double curvature = below - 2 * best_chi2 + above;
    if (std::isfinite(curvature) && curvature > 0) {
      const double vertex = t + 0.5 * step * (below - above) / curvature;
      if (const double c = chi2_at(vertex); c < best_chi2) t = vertex, best_chi2 = c;
    }
  }
  if (on || precise) {
    profiled::golden_refine(chi2_at, lo + std::max(0, best - 1) * step,
                            lo + std::min(grid - 1, best + 1) * step, kRefineSteps, &t, &best_chi2);
  }
  (on ? m->sigma : m->roughness) = to_shape(t);
  pooled_chi2_at(members, w, to_shape(t), m);
}

}  // namespace ls::relight::materials
