#pragma once
// Candidate fits with the linear parameters solved in closed form.
//
// At a fixed normal every model here is linear in its albedos and k_s once its one nonlinear
// parameter is fixed:
//   R_c(l) = albedo_c * a(l) + k_s * b(l),   a = f_diffuse * cos_i,  b = f_lobe * cos_i,
// so for each value of the nonlinear parameter the weighted, non-negative least squares over
// (albedo r g b, k_s) is a 4-unknown problem solved from a handful of sums over the samples, and
// chi^2 follows from the same sums. What depends only on the lights (cosines, the half vector,
// the shadowing term) is computed once per pixel; the nonlinear parameter is searched on a grid
// and refined (sigma by golden section, which costs nothing per sample; the roughness by one
// parabolic step, each pass over the samples costing an exp per sample):
//   Lambert:           a = cos_i / pi, nothing to search.
//   Oren-Nayar:        a = (A(sigma) cos_i + B(sigma) s cos_i) / pi with s = max(0, cos_io -
//                      cos_i cos_o) / max(cos_i, cos_o) independent of sigma, so the sums of the
//                      two terms give chi^2 for any sigma at no cost per sample.
//   Torrance-Sparrow:  b = exp(-tan^2(theta_h) / m^2) / m^2 * K with K independent of m; samples
//                      where the lobe is below e^-40 of its peak are skipped. The roughness is
//                      searched, and polished, no lower than the pixel's resolvable roughness: the
//                      narrowest lobe that still has three samples above 10% of its peak. A lobe
//                      narrower than the spacing of the lights fits one bright sample with any m
//                      (k_s trades against m): the data cannot support it.
// Conventions as relight/fit/pixel_solver.h (values in 1/sr, cos_i outside f, residuals divided
// by the noise sigma).
//
// The candidates hold the normal; polish() then refines a candidate, normal included, by the
// bounded LM (pixel::solve) over its nonlinear parameters only (two normal angles and sigma or
// the roughness), the linear ones solved in closed form inside the cost (variable projection):
// two or three Jet dimensions instead of seven.
#include <Eigen/Core>
#include <limits>
#include <vector>

#include "relight/fit/fit.h"
#include "relight/fit/pixel_solver.h"

namespace ls::relight::profiled {

// One model's best fit at the held normal. ok = false: not fitted (no lit samples), or, for a
// lobe, every lobe that fitted had k_s above the bound (implausible_lobe).
struct Candidate {
  bool ok = false;
  bool implausible_lobe = false;
  double chi2 = std::numeric_limits<double>::infinity();
  Eigen::Vector3d albedo{0, 0, 0};
  double sigma = 0;      // Oren-Nayar, radians.
  double ks = 0;         // Torrance-Sparrow, white.
  double roughness = 0;  // Torrance-Sparrow Beckmann m.
};

// The closed-form weighted non-negative least squares of R_c = albedo_c a + k_s b from the sums
// per channel c of w a a, w a v, w a b, w b b, w b v (w = 1/sigma^2); without a lobe (b = 0) the
// albedos alone. Active set: an albedo that comes out negative is held at 0 and k_s solved again
// without it; k_s is clamped at 0. Templated for Jets (the polish differentiates through it).
template <class T>
struct LinearSums {
  T aa[3], av[3], ab[3], bb[3], bv[3], vv[3];
};
template <class T>
void solve_linear(const LinearSums<T>& s, bool has_lobe, T* albedo, T* ks) {
  bool free[3];
  for (int c = 0; c < 3; ++c) free[c] = s.aa[c] > T(0);
  *ks = T(0);
  for (int round = 0; round < 4; ++round) {
    if (has_lobe) {
      T num(0), den(0);
      for (int c = 0; c < 3; ++c) {
        num += s.bv[c];
        den += s.bb[c];
        if (free[c]) {
          num -= s.ab[c] * s.av[c] / s.aa[c];
          den -= s.ab[c] * s.ab[c] / s.aa[c];
        }
      }
      *ks = den > T(0) && num > T(0) ? num / den : T(0);
    }
    bool changed = false;
    for (int c = 0; c < 3; ++c) {
      albedo[c] = free[c] ? (s.av[c] - s.ab[c] * *ks) / s.aa[c] : T(0);
      if (albedo[c] < T(0)) albedo[c] = T(0), free[c] = false, changed = true;
    }
    if (!changed || !has_lobe) break;
  }
}
// chi^2 of the solution from the same sums (clamped at 0 against rounding).
template <class T>
T chi2_of(const LinearSums<T>& s, const T* albedo, const T& ks) {
  T chi2(0);
  for (int c = 0; c < 3; ++c) {
    chi2 += s.vv[c] - T(2) * (albedo[c] * s.av[c] + ks * s.bv[c]) +
            albedo[c] * albedo[c] * s.aa[c] + T(2) * albedo[c] * ks * s.ab[c] + ks * ks * s.bb[c];
  }
  return chi2 > T(0) ? chi2 : T(0);
}

// Oren-Nayar's sigma is searched on this grid over [0, pi/2] (2.8 degree steps), then refined
// by this many golden-section steps inside the best grid bracket (two steps wide: 6 narrow it to
// 0.04 of a step); per pixel (PixelTerms) and per material (material_pool.h) alike.
constexpr int kSigmaGrid = 33;
constexpr int kRefineSteps = 6;

// Minimises f over [lo, hi] by `steps` golden-section steps, starting from the bracket of a grid
// minimum; x_best and f_best are updated in place where a better argument is seen.
template <class F>
void golden_refine(const F& f, double lo, double hi, int steps, double* x_best, double* f_best) {
  constexpr double kInvPhi = 0.6180339887498949;
  double x1 = hi - kInvPhi * (hi - lo), x2 = lo + kInvPhi * (hi - lo);
  double f1 = f(x1), f2 = f(x2);
  for (int i = 0; i < steps; ++i) {
    if (f1 < f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - kInvPhi * (hi - lo);
      f1 = f(x1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + kInvPhi * (hi - lo);
      f2 = f(x2);
    }
  }
  if (f1 < *f_best) *x_best = x1, *f_best = f1;
  if (f2 < *f_best) *x_best = x2, *f_best = f2;
}

// A pixel's samples reduced to what the candidates need at one normal, structure of arrays.
// Reused across pixels (the vectors keep their capacity).
class PixelTerms {
 public:
  void reset(const pixel::Sample* samples, int count, const Eigen::Vector3d& normal,
             const Eigen::Vector3d& view);

  Candidate lambert() const;
  Candidate oren_nayar() const;
  // refine_steps: golden-section steps on log(roughness) after the grid (fit.cc polishes its
  // candidates by LM instead; the temporal step fits keep them as they are).
  Candidate torrance_sparrow(double max_specular_albedo, int refine_steps = 0) const;
  // Oren-Nayar + Torrance-Sparrow (the temporal step fits' full model): the roughness searched as
  // torrance_sparrow(), sigma at each roughness as oren_nayar().
  Candidate oren_nayar_torrance_sparrow(double max_specular_albedo, int refine_steps = 0) const;
  // The sums of a model (Lambert, Oren-Nayar or Lambert + Torrance-Sparrow) at its nonlinear
  // parameter `shape` (sigma, the roughness; ignored for Lambert): what the candidates solve, and
  // what basis materials pool over pixels (relight/fit/basis_materials.h).
  LinearSums<double> sums(FitModel model, double shape) const;
  // The prediction albedo_c a(l) + k_s b(l) of a model at its shape, per sample and channel
  // (out[3 i + c]), and the samples' weights 1/sigma^2 and values in the same order.
  void predict(FitModel model, double shape, const Eigen::Vector3d& albedo, double ks,
               double* out) const;
  int count() const { return count_; }
  // The sum over the samples of the lobe of this roughness relative to its peak,
  // exp(-tan^2(theta_h) / m^2).
  double lobe_weight(double roughness) const;
  double weight(int i, int c) const { return w_[c][size_t(i)]; }
  double value(int i, int c) const { return v_[c][size_t(i)]; }
  // Whether any sample is lit at the normal (every candidate needs one).
  bool lit() const {
    return lambert_sums_.aa[0] > 0 || lambert_sums_.aa[1] > 0 || lambert_sums_.aa[2] > 0;
  }
  // The lowest roughness the samples resolve (see above), at least pixel::kMinRoughness.
  double min_roughness() const { return min_roughness_; }
  // Searches lobes down to pixel::kMinRoughness after reset(): where the normal is known
  // independently of these samples (the temporal step fits hold it from another step), the peak
  // is placed, and one or two bright samples do set a narrow lobe.
  void search_unresolved_lobes() { min_roughness_ = pixel::kMinRoughness; }

 private:
  // The Lambert + Torrance-Sparrow sums at one roughness; oren_nayar_lobe (3, or null): the
  // per-channel sums of w o b, the lobe's cross term with Oren-Nayar's B term.
  LinearSums<double> lobe_sums(double roughness, double* oren_nayar_lobe) const;

  int count_ = 0;
  std::vector<double> w_[3], v_[3];  // Weight 1/sigma^2 and value, per channel.
  std::vector<double> lambert_;      // cos_i / pi, 0 where unlit.
  std::vector<double> oren_nayar_;   // s cos_i / pi (the B term of Oren-Nayar).
  std::vector<double> tan2_h_;       // tan^2 of the half vector's angle to the normal.
  double min_tan2_h_ = 0;            // Over the samples: the one nearest the mirror direction.
  double min_roughness_ = pixel::kMinRoughness;
  std::vector<double> lobe_scale_;     // Torrance-Sparrow b * m^2 / exp(-tan^2 / m^2).
  std::vector<double> nearest_;        // Scratch for the resolvable roughness.
  LinearSums<double> lambert_sums_{};  // a = lambert_, no lobe.
  // Per channel sums of w o v, w l o, w o o with o = oren_nayar_, l = lambert_.
  double ov_[3] = {0, 0, 0}, lo_[3] = {0, 0, 0}, oo_[3] = {0, 0, 0};
};

struct Polished {
  pixel::SolverStatus status = pixel::SolverStatus::kFailed;
  Candidate fit;
  Eigen::Vector3d normal{0, 0, 0};
};

// The LM polish of a candidate of model (Lambert, Oren-Nayar or Lambert + Torrance-Sparrow),
// normal included, from the candidate's parameters at the pixel's n0; the roughness is kept at or
// above min_roughness (PixelTerms::min_roughness()).
Polished polish(FitModel model, const Candidate& start, const pixel::PixelData& pixel,
                double min_roughness, int max_iterations);

}  // namespace ls::relight::profiled
