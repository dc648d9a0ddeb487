#include "relight/fit/profiled_fit.h"

#include <algorithm>
#include <cmath>

#include "physics/brdf.h"

namespace ls::relight::profiled {
namespace {

using pixel::kPi;

constexpr double kMaxSigma = 0.5 * kPi;
constexpr double kMaxLobeExponent = 40;  // exp(-40) ~ 4e-18 of the lobe's peak: skipped.
constexpr int kRoughnessGrid = 10;       // Log-spaced over [min_roughness, 1].
constexpr int kResolvingSamples = 3;     // A lobe needs this many samples above 10% of its peak.
// The polish stops once a step lowers chi^2 by less than this, in units of the fit's own residual
// scale (polish_tolerance): a tenth of the change that matters to a BIC comparison or to a 1-sigma
// interval (1 unit). 1e-3 took a third more iterations on the DiLiGenT objects for a mean normal
// error 0.01 (ball) and 0.06 degrees (reading) lower (scripts/bench_fit_real.py).
constexpr double kPolishChi2Tolerance = 0.1;

// kPolishChi2Tolerance in chi^2 units for a start at chi^2 with `parameters` free over `residuals`:
// scaled by the reduced chi^2 where it exceeds 1, since a pixel no model explains (an occluding
// edge, an interreflection) has residuals that many times its noise, and there the polish would
// otherwise crawl on changes far below what separates its parameters.
double polish_tolerance(double chi2, int residuals, int parameters) {
  return kPolishChi2Tolerance * std::max(1.0, chi2 / std::max(1, residuals - parameters));
}

// Oren-Nayar's A and B of sigma (physics/brdf.h).
void oren_nayar_ab(double sigma, double* a, double* b) {
  const double s2 = sigma * sigma;
  *a = 1 - 0.5 * s2 / (s2 + 0.33);
  *b = 0.45 * s2 / (s2 + 0.09);
}

}  // namespace

void PixelTerms::reset(const pixel::Sample* samples, int count, const Eigen::Vector3d& normal,
                       const Eigen::Vector3d& view) {
  count_ = count;
  for (int c = 0; c < 3; ++c) {
    w_[c].resize(size_t(count));
    v_[c].resize(size_t(count));
    ov_[c] = lo_[c] = oo_[c] = 0;
  }
  lambert_sums_ = LinearSums<double>{};
  lambert_.resize(size_t(count));
  oren_nayar_.resize(size_t(count));
  tan2_h_.resize(size_t(count));
  lobe_scale_.resize(size_t(count));
  min_tan2_h_ = HUGE_VAL;
  const double cos_o = normal.dot(view);
  for (int i = 0; i < count; ++i) {
    const pixel::Sample& s = samples[i];
    const double cos_i = normal.dot(s.l), cos_io = s.l.dot(view);
    double lambert = 0, oren_nayar = 0, tan2_h = HUGE_VAL, lobe_scale = 0;
    if (cos_i > 0 && cos_o > 0) {  // Every model is 0 with either direction below the surface.
      lambert = cos_i / kPi;
      oren_nayar = lambert * std::max(0.0, cos_io - cos_i * cos_o) / std::max(cos_i, cos_o);
      const double len2 = 2 + 2 * cos_io;  // |wi + wo|^2
      if (len2 > 1e-12) {
        const double inv_len = 1 / std::sqrt(len2);
        const double cos_h = (cos_i + cos_o) * inv_len, cos_oh = (1 + cos_io) * inv_len;
        const double cos_h2 = cos_h * cos_h;
        const double shadowing =
            std::min({1.0, 2 * cos_h * cos_o / cos_oh, 2 * cos_h * cos_i / cos_oh});
        tan2_h = (1 - cos_h2) / cos_h2;
        lobe_scale = shadowing / (4 * kPi * cos_h2 * cos_h2 * cos_o);
      }
    }
    lambert_[i] = lambert;
    oren_nayar_[i] = oren_nayar;
    tan2_h_[i] = tan2_h;
    min_tan2_h_ = std::min(min_tan2_h_, tan2_h);
    lobe_scale_[i] = lobe_scale;
    for (int c = 0; c < 3; ++c) {
      const double w = s.inv_sigma[c] * s.inv_sigma[c], v = s.v[c];
      w_[c][i] = w;
      v_[c][i] = v;
      lambert_sums_.vv[c] += w * v * v;
      lambert_sums_.av[c] += w * lambert * v;
      lambert_sums_.aa[c] += w * lambert * lambert;
      ov_[c] += w * oren_nayar * v;
      lo_[c] += w * lambert * oren_nayar;
      oo_[c] += w * oren_nayar * oren_nayar;
    }
  }
  // The third-nearest sample to the mirror direction sets the narrowest resolvable lobe:
  // exp(-tan^2 / m^2) = 0.1 there.
  min_roughness_ = pixel::kMinRoughness;
  if (count >= kResolvingSamples) {
    nearest_.assign(tan2_h_.begin(), tan2_h_.end());
    std::nth_element(nearest_.begin(), nearest_.begin() + (kResolvingSamples - 1), nearest_.end());
    const double tan2 = nearest_[kResolvingSamples - 1];
    if (std::isfinite(tan2)) {
      min_roughness_ = std::clamp(std::sqrt(tan2 / std::log(10.0)), pixel::kMinRoughness, 0.5);
    }
  }
}

Candidate PixelTerms::lambert() const {
  Candidate out;
  const LinearSums<double>& s = lambert_sums_;
  out.ok = lit();
  double ks;
  solve_linear(s, /*has_lobe=*/false, out.albedo.data(), &ks);
  out.chi2 = chi2_of(s, out.albedo.data(), 0.0);
  return out;
}

Candidate PixelTerms::oren_nayar() const {
  if (!lit()) return {};
  auto chi2_at = [&](double sigma, Eigen::Vector3d* albedo) {
    const LinearSums<double> s = sums(FitModel::kOrenNayar, sigma);
    Eigen::Vector3d x;
    double ks;
    solve_linear(s, /*has_lobe=*/false, x.data(), &ks);
    if (albedo) *albedo = x;
    return chi2_of(s, x.data(), 0.0);
  };
  auto chi2_of_sigma = [&](double sigma) { return chi2_at(sigma, nullptr); };
  const double step = kMaxSigma / (kSigmaGrid - 1);
  int best = 0;
  double best_chi2 = HUGE_VAL;
  for (int k = 0; k < kSigmaGrid; ++k) {
    const double chi2 = chi2_of_sigma(k * step);
    if (chi2 < best_chi2) best = k, best_chi2 = chi2;
  }
  Candidate out;
  out.sigma = best * step;
  golden_refine(chi2_of_sigma, std::max(0, best - 1) * step,
                std::min(kSigmaGrid - 1, best + 1) * step, kRefineSteps, &out.sigma, &best_chi2);
  out.chi2 = chi2_at(out.sigma, &out.albedo);
  out.ok = true;
  return out;
}

LinearSums<double> PixelTerms::sums(FitModel model, double shape) const {
  if (model == FitModel::kLambertTorranceSparrow) return lobe_sums(shape, nullptr);
  if (model != FitModel::kOrenNayar) return lambert_sums_;
  // a = A lambert + B oren_nayar: the sums of the two terms give any sigma's at no cost.
  double a, b;
  oren_nayar_ab(shape, &a, &b);
  LinearSums<double> s = lambert_sums_;
  for (int c = 0; c < 3; ++c) {
    s.aa[c] = a * a * lambert_sums_.aa[c] + 2 * a * b * lo_[c] + b * b * oo_[c];
    s.av[c] = a * lambert_sums_.av[c] + b * ov_[c];
  }
  return s;
}

void PixelTerms::predict(FitModel model, double shape, const Eigen::Vector3d& albedo, double ks,
                         double* out) const {
  double a_scale = 1, b_scale = 0;
  if (model == FitModel::kOrenNayar) oren_nayar_ab(shape, &a_scale, &b_scale);
  const double inv_m2 = model == FitModel::kLambertTorranceSparrow ? 1 / (shape * shape) : 0;
  for (int i = 0; i < count_; ++i) {
    const double a = a_scale * lambert_[i] + b_scale * oren_nayar_[i];
    const double exponent = tan2_h_[i] * inv_m2;
    const double b = inv_m2 > 0 && exponent <= kMaxLobeExponent
                         ? lobe_scale_[i] * inv_m2 * std::exp(-exponent)
                         : 0.0;
    for (int c = 0; c < 3; ++c) out[3 * i + c] = albedo(c) * a + ks * b;
  }
}

double PixelTerms::lobe_weight(double roughness) const {
  const double inv_m2 = 1 / (roughness * roughness);
  double sum = 0;
  for (int i = 0; i < count_; ++i) {
    if (tan2_h_[i] * inv_m2 <= kMaxLobeExponent) sum += std::exp(-tan2_h_[i] * inv_m2);
  }
  return sum;
}

LinearSums<double> PixelTerms::lobe_sums(double roughness, double* oren_nayar_lobe) const {
  LinearSums<double> sums = lambert_sums_;
  if (oren_nayar_lobe) std::fill_n(oren_nayar_lobe, 3, 0.0);
  const double inv_m2 = 1 / (roughness * roughness);
  if (min_tan2_h_ * inv_m2 > kMaxLobeExponent) return sums;  // No sample sees this lobe.
  for (int i = 0; i < count_; ++i) {
    const double exponent = tan2_h_[i] * inv_m2;
    if (exponent > kMaxLobeExponent) continue;
    // A float exp: a sixth of the grid's cost; its 1e-7 relative error changes a lobe's chi^2 by
    // far less than the tolerance of any comparison made with it.
    const double b = lobe_scale_[i] * inv_m2 * std::exp(-float(exponent));
    for (int c = 0; c < 3; ++c) {
      const double wb = w_[c][i] * b;
      sums.ab[c] += wb * lambert_[i];
      sums.bb[c] += wb * b;
      sums.bv[c] += wb * v_[c][i];
      if (oren_nayar_lobe) oren_nayar_lobe[c] += wb * oren_nayar_[i];
    }
  }
  return sums;
}

namespace {

// The best of fit_at(roughness) over log(roughness) in [min_roughness, 1]: a grid, then one
// parabolic step through the best point and its two neighbours, then `refine_steps` golden-section
// steps inside that bracket (each pass costs an exp per sample). A lobe with k_s above the bound
// comes back with chi^2 infinite; none below it: implausible_lobe.
template <class FitAt>
Candidate search_roughness(const FitAt& fit_at, double min_roughness, int refine_steps) {
  const double lo = std::log(min_roughness), step = -lo / (kRoughnessGrid - 1);
  double chi2[kRoughnessGrid];
  int best = 0;
  Candidate out;
  for (int k = 0; k < kRoughnessGrid; ++k) {
    const Candidate c = fit_at(std::exp(lo + k * step));
    chi2[k] = c.chi2;
    if (c.chi2 < out.chi2) best = k, out = c;
  }
  if (!out.ok) {
    out.implausible_lobe = true;
    return out;
  }
  if (best > 0 && best < kRoughnessGrid - 1 && std::isfinite(chi2[best - 1]) &&
      std::isfinite(chi2[best + 1])) {
    const double curvature = chi2[best - 1] - 2 * chi2[best] + chi2[best + 1];
    if (curvature > 0) {
      const double offset = 0.5 * (chi2[best - 1] - chi2[best + 1]) / curvature;  // In steps.
      const Candidate c = fit_at(std::exp(lo + (best + std::clamp(offset, -1.0, 1.0)) * step));
      if (c.chi2 < out.chi2) out = c;
    }
  }
  if (refine_steps > 0) {
    double log_m = std::log(out.roughness), f_best = out.chi2;
    golden_refine(
        [&](double x) { return fit_at(std::exp(x)).chi2; }, lo + std::max(0, best - 1) * step,
        lo + std::min(kRoughnessGrid - 1, best + 1) * step, refine_steps, &log_m, &f_best);
    if (f_best < out.chi2) out = fit_at(std::exp(log_m));
  }
  return out;
}

}  // namespace

Candidate PixelTerms::torrance_sparrow(double max_specular_albedo, int refine_steps) const {
  if (!lit()) return {};
  // The fit at a roughness; a lobe with k_s above the bound counts as no fit (chi^2 infinite).
  auto fit_at = [&](double roughness) {
    const LinearSums<double> sums = lobe_sums(roughness, nullptr);
    Candidate c;
    solve_linear(sums, /*has_lobe=*/true, c.albedo.data(), &c.ks);
    c.chi2 = c.ks > max_specular_albedo ? HUGE_VAL : chi2_of(sums, c.albedo.data(), c.ks);
    c.roughness = roughness;
    c.ok = std::isfinite(c.chi2);
    return c;
  };
  return search_roughness(fit_at, min_roughness_, refine_steps);
}

Candidate PixelTerms::oren_nayar_torrance_sparrow(double max_specular_albedo,
                                                  int refine_steps) const {
  if (!lit()) return {};
  // At a roughness, the diffuse term a = A lambert + B oren_nayar and its cross term with the lobe
  // follow from the lobe's sums with each of the two: every sigma is then free, searched as
  // oren_nayar() does.
  auto fit_at = [&](double roughness) {
    double oren_nayar_lobe[3];
    const LinearSums<double> lobe = lobe_sums(roughness, oren_nayar_lobe);
    auto fit_sigma = [&](double sigma) {
      LinearSums<double> s = sums(FitModel::kOrenNayar, sigma);
      double a, b;
      oren_nayar_ab(sigma, &a, &b);
      for (int c = 0; c < 3; ++c) {
        s.ab[c] = a * lobe.ab[c] + b * oren_nayar_lobe[c];
        s.bb[c] = lobe.bb[c];
        s.bv[c] = lobe.bv[c];
      }
      Candidate out;
      solve_linear(s, /*has_lobe=*/true, out.albedo.data(), &out.ks);
      out.chi2 = out.ks > max_specular_albedo ? HUGE_VAL : chi2_of(s, out.albedo.data(), out.ks);
      out.sigma = sigma;
      out.roughness = roughness;
      out.ok = std::isfinite(out.chi2);
      return out;
    };
    // A coarser grid than oren_nayar()'s and more golden steps: the same precision for half the
    // solves, which this search repeats at every roughness.
    constexpr int kGrid = (kSigmaGrid - 1) / 4 + 1, kSteps = kRefineSteps + 3;
    const double step = kMaxSigma / (kGrid - 1);
    int best = 0;
    double best_chi2 = HUGE_VAL;
    for (int k = 0; k < kGrid; ++k) {
      const double chi2 = fit_sigma(k * step).chi2;
      if (chi2 < best_chi2) best = k, best_chi2 = chi2;
    }
    if (!std::isfinite(best_chi2)) return Candidate{};
    double sigma = best * step;
    golden_refine([&](double x) { return fit_sigma(x).chi2; }, std::max(0, best - 1) * step,
                  std::min(kGrid - 1, best + 1) * step, kSteps, &sigma, &best_chi2);
    return fit_sigma(sigma);
  };
  return search_roughness(fit_at, min_roughness_, refine_steps);
}

namespace {

// The polish's parameters: two normal angles (held at 0 without refine_normal) and sigma or the
// roughness through their bounded maps.

template <FitModel M, class T>
T shape_of(const T* x, double min_m) {
  if constexpr (M == FitModel::kOrenNayar) return pixel::bounded(x[2], 0.0, kMaxSigma);
  if constexpr (M == FitModel::kLambertTorranceSparrow) return pixel::bounded(x[2], min_m, 1.0);
  return T(0);
}

// A sample's geometry that the polish does not change: wi.wo and the half vector's length and
// angle to the view (physics::brdf::torrance_sparrow_half), computed once per polish, not once per
// step.
struct SampleConstants {
  double cos_io = 0, inv_len = 0, cos_oh = 0;
};

const std::vector<SampleConstants>& sample_constants(const pixel::PixelData& p) {
  thread_local std::vector<SampleConstants> out;
  out.resize(size_t(p.count));
  for (int i = 0; i < p.count; ++i) {
    SampleConstants& k = out[size_t(i)];
    k.cos_io = p.samples[i].l.dot(p.wo);
    const double len2 = 2 + 2 * k.cos_io;                  // |wi + wo|^2
    k.inv_len = len2 > 1e-12 ? 1 / std::sqrt(len2) : 0.0;  // 0: no half vector, no lobe.
    k.cos_oh = (1 + k.cos_io) * k.inv_len;
  }
  return out;
}

// The model's terms a (multiplying the albedo) and b (multiplying k_s) per sample at x, and
// their sums. The cosines are the only per-sample Jets: everything else is a double.
template <FitModel M, class T>
LinearSums<T> terms_at(const pixel::PixelData& p, const std::vector<SampleConstants>& constants,
                       double min_roughness, const T* x, std::vector<T>* a, std::vector<T>* b) {
  constexpr bool kLobe = M == FitModel::kLambertTorranceSparrow;
  const physics::brdf::Vec3<T> n = pixel::refined_normal(p, x);
  const T cos_o = n.x() * p.wo.x() + n.y() * p.wo.y() + n.z() * p.wo.z();
  const T shape = shape_of<M>(x, min_roughness);
  LinearSums<T> s;
  for (int c = 0; c < 3; ++c) s.aa[c] = s.av[c] = s.ab[c] = s.bb[c] = s.bv[c] = s.vv[c] = T(0);
  a->resize(size_t(p.count));
  b->resize(size_t(p.count));
  for (int i = 0; i < p.count; ++i) {
    const pixel::Sample& sample = p.samples[i];
    const SampleConstants& k = constants[size_t(i)];
    const T cos_i = n.x() * sample.l.x() + n.y() * sample.l.y() + n.z() * sample.l.z();
    T ai(0), bi(0);
    if (cos_i > T(0) && cos_o > T(0)) {  // Every model is 0 with either direction below.
      if constexpr (M == FitModel::kOrenNayar) {
        ai = physics::brdf::oren_nayar(physics::brdf::Geometry<T>{cos_i, cos_o, T(k.cos_io)},
                                       shape) *
             cos_i;
      } else {
        ai = cos_i * (1 / kPi);
      }
      if constexpr (kLobe) {
        bi = physics::brdf::torrance_sparrow_half(cos_i, cos_o, k.inv_len, k.cos_oh, shape) * cos_i;
      }
    }
    (*a)[i] = ai;
    (*b)[i] = bi;
    const T aa = ai * ai;
    for (int c = 0; c < 3; ++c) {
      const double w = sample.inv_sigma[c] * sample.inv_sigma[c], wv = w * sample.v[c];
      s.aa[c] += aa * w;
      s.av[c] += ai * wv;
      s.vv[c] += T(wv * sample.v[c]);
    }
    if constexpr (kLobe) {
      const T ab = ai * bi, bb = bi * bi;
      for (int c = 0; c < 3; ++c) {
        const double w = sample.inv_sigma[c] * sample.inv_sigma[c];
        s.ab[c] += ab * w;
        s.bb[c] += bb * w;
        s.bv[c] += bi * (w * sample.v[c]);
      }
    }
  }
  return s;
}

// Residuals at x with the albedos and k_s in closed form (variable projection).
template <FitModel M>
struct ProfiledCost {
  const pixel::PixelData* p;
  const std::vector<SampleConstants>* constants;
  double min_roughness;
  int NumResiduals() const { return 3 * p->count; }

  template <class T>
  bool operator()(const T* x, T* r) const {
    thread_local std::vector<T> a, b;
    const LinearSums<T> s = terms_at<M>(*p, *constants, min_roughness, x, &a, &b);
    T albedo[3], ks;
    solve_linear(s, M == FitModel::kLambertTorranceSparrow, albedo, &ks);
    for (int i = 0; i < p->count; ++i) {
      const pixel::Sample& sample = p->samples[i];
      for (int c = 0; c < 3; ++c) {
        T predicted = albedo[c] * a[i];
        if constexpr (M == FitModel::kLambertTorranceSparrow) predicted += ks * b[i];
        r[3 * i + c] = (predicted - sample.v[c]) * sample.inv_sigma[c];
      }
    }
    return true;
  }
};

// Lambert over its five parameters (two normal angles, sqrt(albedo) r g b) with the Jacobian in
// closed form: the polish that most pixels get, three times cheaper than Jets.
struct LambertCost {
  using Scalar = double;
  enum { NUM_RESIDUALS = Eigen::Dynamic, NUM_PARAMETERS = 5 };
  const pixel::PixelData* p;
  int NumResiduals() const { return 3 * p->count; }

  bool operator()(const double* x, double* r, double* jacobian = nullptr) const {
    const Eigen::Vector3d m = p->n0 + p->t1 * x[0] + p->t2 * x[1];
    const double inv_len = 1 / m.norm();
    const Eigen::Vector3d n = m * inv_len;
    // dn/dx0 and dn/dx1 of n = m / |m|.
    const Eigen::Vector3d dn0 = (p->t1 - n * n.dot(p->t1)) * inv_len;
    const Eigen::Vector3d dn1 = (p->t2 - n * n.dot(p->t2)) * inv_len;
    const bool viewed = n.dot(p->wo) > 0;
    const int rows = NumResiduals();
    for (int i = 0; i < p->count; ++i) {
      const pixel::Sample& s = p->samples[i];
      const double cos_i = n.dot(s.l);
      const bool lit = viewed && cos_i > 0;
      const double shade = lit ? cos_i / kPi : 0.0;
      for (int c = 0; c < 3; ++c) {
        const double u = x[2 + c], albedo = u * u, weight = s.inv_sigma[c];
        const int row = 3 * i + c;
        r[row] = (albedo * shade - s.v[c]) * weight;
        if (!jacobian) continue;
        const double d_shade = lit ? albedo * weight / kPi : 0.0;
        jacobian[row] = d_shade * dn0.dot(s.l);
        jacobian[rows + row] = d_shade * dn1.dot(s.l);
        for (int k = 0; k < 3; ++k) jacobian[(2 + k) * rows + row] = 0;
        jacobian[(2 + c) * rows + row] = 2 * u * shade * weight;
      }
    }
    return true;
  }
};

// Over the samples lit at n0, Lambert's chi^2 per channel is a quadratic form in g_c = albedo_c
// n / pi: sum_i w_ic (g_c . l_i - v_ic)^2 = |U_c g_c - z_c|^2 + const, with U_c^T U_c = S_c =
// sum_i w_ic l_i l_i^T and U_c^T z_c = sum_i w_ic v_ic l_i. The polish then runs on 9 residuals
// instead of 3 per sample; it holds while no sample crosses the terminator (the polish tilts the
// normal by a small angle), and chi^2 is evaluated over every sample after it.
struct LambertQuadratic {
  enum { NUM_RESIDUALS = 9, NUM_PARAMETERS = 5 };  // Two normal angles, sqrt(albedo) r g b.
  Eigen::Matrix3d u[3];
  Eigen::Vector3d z[3];
  const pixel::PixelData* p = nullptr;

  // False when the lit samples do not span three directions in some channel.
  bool build(const pixel::PixelData& problem) {
    p = &problem;
    Eigen::Matrix3d s[3] = {Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Zero(),
                            Eigen::Matrix3d::Zero()};
    Eigen::Vector3d b[3] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                            Eigen::Vector3d::Zero()};
    const bool viewed = problem.n0.dot(problem.wo) > 0;
    for (int i = 0; i < problem.count && viewed; ++i) {
      const pixel::Sample& sample = problem.samples[i];
      if (!(problem.n0.dot(sample.l) > 0)) continue;
      const Eigen::Matrix3d ll = sample.l * sample.l.transpose();
      for (int c = 0; c < 3; ++c) {
        const double w = sample.inv_sigma[c] * sample.inv_sigma[c];
        s[c].noalias() += w * ll;
        b[c].noalias() += (w * sample.v[c]) * sample.l;
      }
    }
    for (int c = 0; c < 3; ++c) {
      const Eigen::LLT<Eigen::Matrix3d> llt(s[c]);
      if (llt.info() != Eigen::Success) return false;
      u[c] = llt.matrixU();
      z[c] = llt.matrixL().solve(b[c]);
    }
    return true;
  }

  // Whether every sample is lit at normal n as it is at n0.
  bool holds_at(const Eigen::Vector3d& n) const {
    if ((n.dot(p->wo) > 0) != (p->n0.dot(p->wo) > 0)) return false;
    for (int i = 0; i < p->count; ++i) {
      if ((n.dot(p->samples[i].l) > 0) != (p->n0.dot(p->samples[i].l) > 0)) return false;
    }
    return true;
  }

  template <class T>
  bool operator()(const T* x, T* r) const {
    const physics::brdf::Vec3<T> n = pixel::refined_normal(*p, x);
    for (int c = 0; c < 3; ++c) {
      const physics::brdf::Vec3<T> g = n * (x[2 + c] * x[2 + c] / kPi);
      for (int k = 0; k < 3; ++k) r[3 * c + k] = u[c].row(k).cast<T>().dot(g) - T(z[c](k));
    }
    return true;
  }
};

Polished polish_lambert(const Candidate& start, const pixel::PixelData& problem,
                        int max_iterations) {
  Eigen::Matrix<double, 5, 1> x0;
  x0 << 0, 0, pixel::non_negative_inverse(start.albedo(0), 1e-8),
      pixel::non_negative_inverse(start.albedo(1), 1e-8),
      pixel::non_negative_inverse(start.albedo(2), 1e-8);
  const LambertCost cost{&problem};
  const double tolerance = polish_tolerance(start.chi2, cost.NumResiduals(), 5);
  thread_local LambertQuadratic quadratic;
  pixel::SolveResult<5> solved;
  if (quadratic.build(problem)) {
    solved =
        pixel::solve_function(ceres::TinySolverAutoDiffFunction<LambertQuadratic, 9, 5>(quadratic),
                              cost, x0, max_iterations, tolerance);
  }
  // Where the normal moved far enough to light or shadow a sample, the quadratic no longer is
  // chi^2: the polish runs over every sample.
  if (!solved.usable() || !quadratic.holds_at(pixel::refined_normal(problem, solved.x.data()))) {
    solved = pixel::solve_function(cost, cost, x0, max_iterations, tolerance);
  }
  Polished out;
  out.status = solved.status;
  if (!solved.usable()) return out;
  const Eigen::Matrix<double, 5, 1>& x = solved.x;
  out.normal = pixel::refined_normal(problem, x.data());
  out.fit.albedo = Eigen::Vector3d(x(2) * x(2), x(3) * x(3), x(4) * x(4));
  out.fit.chi2 = solved.chi2;
  out.fit.ok = out.normal.allFinite() && out.fit.albedo.allFinite();
  if (!out.fit.ok) out.status = pixel::SolverStatus::kFailed;
  return out;
}

template <FitModel M>
Polished polish_model(const Candidate& start, const pixel::PixelData& problem, double min_roughness,
                      int max_iterations) {
  constexpr int K = 3;
  Eigen::Matrix<double, K, 1> x0 = Eigen::Matrix<double, K, 1>::Zero();
  if constexpr (M == FitModel::kOrenNayar) {
    x0(2) = pixel::clamped_bounded_inverse(start.sigma, 0.0, kMaxSigma);
  }
  if constexpr (M == FitModel::kLambertTorranceSparrow) {
    x0(2) = pixel::clamped_bounded_inverse(start.roughness, min_roughness, 1.0);
  }
  Polished out;
  const std::vector<SampleConstants>& constants = sample_constants(problem);
  const ProfiledCost<M> cost{&problem, &constants, min_roughness};
  // The angles, the shape and the albedos, with k_s where the model has a lobe.
  constexpr int kParameters = M == FitModel::kLambertTorranceSparrow ? 7 : 6;
  const pixel::SolveResult<K> solved = pixel::solve(
      cost, x0, max_iterations, polish_tolerance(start.chi2, cost.NumResiduals(), kParameters));
  out.status = solved.status;
  if (!solved.usable()) return out;
  std::vector<double> a, b;
  const LinearSums<double> s =
      terms_at<M>(problem, constants, min_roughness, solved.x.data(), &a, &b);
  Candidate& fit = out.fit;
  solve_linear(s, M == FitModel::kLambertTorranceSparrow, fit.albedo.data(), &fit.ks);
  fit.chi2 = solved.chi2;
  const double shape = shape_of<M>(solved.x.data(), min_roughness);
  if constexpr (M == FitModel::kOrenNayar) fit.sigma = shape;
  if constexpr (M == FitModel::kLambertTorranceSparrow) fit.roughness = shape;
  out.normal = pixel::refined_normal(problem, solved.x.data());
  fit.ok = out.normal.allFinite() && fit.albedo.allFinite() && std::isfinite(fit.ks) &&
           std::isfinite(fit.sigma) && std::isfinite(fit.roughness);
  if (!fit.ok) out.status = pixel::SolverStatus::kFailed;
  return out;
}

}  // namespace

Polished polish(FitModel model, const Candidate& start, const pixel::PixelData& problem,
                double min_roughness, int max_iterations) {
  switch (model) {
    case FitModel::kLambert:
      if (!problem.refine_normal) return {pixel::SolverStatus::kConverged, start, problem.n0};
      return polish_lambert(start, problem, max_iterations);
    case FitModel::kOrenNayar:
      return polish_model<FitModel::kOrenNayar>(start, problem, min_roughness, max_iterations);
    case FitModel::kLambertTorranceSparrow:
      return polish_model<FitModel::kLambertTorranceSparrow>(start, problem, min_roughness,
                                                             max_iterations);
    default:
      return {};
  }
}

}  // namespace ls::relight::profiled
