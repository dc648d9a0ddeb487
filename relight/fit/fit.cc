#include "relight/fit/fit.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <limits>
#include <mutex>
#include <sstream>

#include "lightstage/errors.h"
#include "physics/brdf.h"
#include "relight/fit/basis_materials.h"
#include "relight/fit/model_render.h"
#include "relight/fit/pixel_solver.h"
#include "relight/fit/profiled_fit.h"

namespace ls::relight {
namespace {

using pixel::kMinRoughness;
using pixel::kPi;
using pixel::PixelData;
using pixel::Sample;
using pixel::SolverStatus;

constexpr double kMaxPhongExponent = 1e4;

template <FitModel M>
constexpr int kNumParams = M == FitModel::kLambert     ? 5
                           : M == FitModel::kOrenNayar ? 6
                                                       : 7;

// Parameter vector: [normal angle a, normal angle b (pixel::refined_normal), sqrt(albedo) r g b,
// model-specific...].

// The model's physical parameters from the raw ones (bounds as in fit.h): sigma, k_s and the lobe
// shape (Beckmann m, or the Phong exponent).
template <FitModel M, class T>
void lobe_params(const T* p, T* sigma, T* ks, T* shape) {
  *sigma = *ks = *shape = T(0);
  if constexpr (M == FitModel::kOrenNayar) *sigma = pixel::bounded(p[5], 0.0, 0.5 * kPi);
  if constexpr (M == FitModel::kLambertTorranceSparrow) {
    *ks = pixel::non_negative(p[5]);
    *shape = pixel::bounded(p[6], kMinRoughness, 1.0);
  }
  if constexpr (M == FitModel::kLambertPhong) {
    *ks = pixel::non_negative(p[5]);
    *shape = pixel::bounded(p[6], 1.0, kMaxPhongExponent);
  }
}

template <FitModel M>
struct Cost {
  const PixelData* d;
  int NumResiduals() const { return 3 * d->count; }

  template <class T>
  bool operator()(const T* p, T* r) const {
    const T albedo[3] = {pixel::non_negative(p[2]), pixel::non_negative(p[3]),
                         pixel::non_negative(p[4])};
    T sigma, ks, shape;
    lobe_params<M>(p, &sigma, &ks, &shape);
    const auto diffuse = [&](const physics::brdf::Geometry<T>& g) {
      if constexpr (M == FitModel::kOrenNayar) return physics::brdf::oren_nayar(g, sigma);
      return physics::brdf::lambert(g);
    };
    const auto specular = [&](const physics::brdf::Geometry<T>& g) {
      if constexpr (M == FitModel::kLambertTorranceSparrow) {
        return ks * physics::brdf::torrance_sparrow(g, shape);
      }
      if constexpr (M == FitModel::kLambertPhong) return ks * physics::brdf::phong(g, shape);
      return T(0);
    };
    pixel::sample_residuals(d->samples, d->count, pixel::refined_normal(*d, p),
                            physics::brdf::Vec3<T>(d->wo.cast<T>()), albedo, diffuse, specular, r);
    return true;
  }
};

struct ModelFit {
  bool ok = false;
  SolverStatus status = SolverStatus::kFailed;
  double chi2 = std::numeric_limits<double>::infinity();
  double bic = std::numeric_limits<double>::infinity();
  int k = 0;
  Eigen::Vector3d normal{0, 0, 0}, albedo{0, 0, 0};
  double sigma = 0, ks = 0, roughness = 0;
  std::array<double, 7> x{};  // Raw parameters, to start the next model from.
};

template <FitModel M>
ModelFit run_fit(const PixelData& d, const std::array<double, 7>& start, int max_iterations) {
  constexpr int K = kNumParams<M>;
  const Eigen::Matrix<double, K, 1> x0 =
      Eigen::Map<const Eigen::Matrix<double, K, 1>>(start.data());
  const pixel::SolveResult<K> solved = pixel::solve(Cost<M>{&d}, x0, max_iterations);
  const Eigen::Matrix<double, K, 1>& x = solved.x;
  ModelFit fit;
  fit.status = solved.status;
  fit.k = model_parameters(M, d.refine_normal);
  if (!solved.usable()) return fit;
  fit.chi2 = solved.chi2;
  fit.bic = fit.chi2 + fit.k * std::log(double(3 * d.count));
  for (int i = 0; i < K; ++i) fit.x[i] = x(i);
  fit.normal = pixel::refined_normal(d, x.data());
  fit.albedo = Eigen::Vector3d(x(2) * x(2), x(3) * x(3), x(4) * x(4));
  double shape;
  lobe_params<M>(x.data(), &fit.sigma, &fit.ks, &shape);
  if constexpr (M == FitModel::kLambertTorranceSparrow) fit.roughness = shape;
  if constexpr (M == FitModel::kLambertPhong) fit.roughness = std::sqrt(2 / (shape + 2));
  fit.ok = fit.normal.allFinite() && fit.albedo.allFinite() && std::isfinite(fit.sigma) &&
           std::isfinite(fit.ks) && std::isfinite(fit.roughness);
  return fit;
}

// Lambert + Phong (a comparison only) by LM from the Lambert fit's raw parameters.
ModelFit fit_phong(const PixelData& d, std::array<double, 7> start, const FitOptions& options,
                   std::array<bool, 5>* implausible) {
  start[5] = std::sqrt(0.05);
  start[6] = pixel::bounded_inverse(50.0, 1.0, kMaxPhongExponent);  // Exponent 50.
  ModelFit fit = run_fit<FitModel::kLambertPhong>(d, start, options.max_iterations);
  if (fit.ok && fit.ks > options.max_specular_albedo) {
    (*implausible)[4] = true;
    return {};
  }
  return fit;
}

// Every candidate model's fit, indexed by FitModel (not ok: not tried or discarded);
// implausible[k]: a lobe fit of model k was thrown away for k_s > max_specular_albedo.
std::array<ModelFit, 5> fit_candidates_by_lm(const PixelData& d, const FitOptions& options,
                                             std::array<bool, 5>* implausible) {
  // Lambert start: closed-form albedo per channel with the PS normal.
  std::array<double, 7> start{};
  const Eigen::Vector3d albedo = pixel::lambert_albedo(d.samples, d.count, d.n0);
  for (int c = 0; c < 3; ++c) start[2 + c] = pixel::non_negative_inverse(albedo(c), 1e-4);
  std::array<ModelFit, 5> fits;
  fits[1] = run_fit<FitModel::kLambert>(d, start, options.max_iterations);
  if (fits[1].ok) start = fits[1].x;
  if (options.fit_oren_nayar) {
    std::array<double, 7> s = start;
    for (int c = 2; c < 5; ++c) s[c] *= 1.07;             // A(sigma) ~ 0.87 at the start sigma.
    s[5] = pixel::bounded_inverse(0.42, 0.0, 0.5 * kPi);  // sigma = 0.42 rad (24 degrees).
    fits[2] = run_fit<FitModel::kOrenNayar>(d, s, options.max_iterations);
  }
  if (options.fit_torrance_sparrow) {
    for (const double m0 : options.roughness_starts) {
      std::array<double, 7> s = start;
      s[5] = std::sqrt(0.05);
      s[6] = pixel::bounded_inverse(m0, kMinRoughness, 1.0);
      ModelFit f = run_fit<FitModel::kLambertTorranceSparrow>(d, s, options.max_iterations);
      if (f.ok && f.ks > options.max_specular_albedo) {
        (*implausible)[3] = true;
        continue;
      }
      if (f.ok && f.bic < fits[3].bic) fits[3] = f;
    }
  }
  if (options.fit_phong) fits[4] = fit_phong(d, start, options, implausible);
  return fits;
}

// A closed-form candidate (relight/fit/profiled_fit.h) as a ModelFit at the given normal.
ModelFit to_model_fit(const profiled::Candidate& c, FitModel model, const Eigen::Vector3d& normal,
                      const PixelData& d) {
  ModelFit fit;
  if (!c.ok) return fit;
  fit.ok = true;
  fit.status = SolverStatus::kConverged;
  fit.k = model_parameters(model, d.refine_normal);
  fit.chi2 = c.chi2;
  fit.bic = c.chi2 + fit.k * std::log(double(3 * d.count));
  fit.normal = normal;
  fit.albedo = c.albedo;
  fit.sigma = c.sigma;
  fit.ks = c.ks;
  fit.roughness = c.roughness;
  for (int i = 0; i < 3; ++i) fit.x[2 + i] = pixel::non_negative_inverse(c.albedo(i), 1e-4);
  return fit;
}

// Candidates whose closed-form BIC is within this of the polished best's, after crediting them
// with the best's gain from polishing, are polished too: refining the normal could still make one
// of them best. 2 = a BIC weight of e^-1 (37%); wider margins polish nearly every candidate of
// every pixel (a nested model is always within its penalty of the simpler one) for no change
// in the choice on the fit tests.
constexpr double kPolishMargin = 2;

// A pixel whose best candidate leaves residuals of 10 sigma rms (reduced chi^2 100) is explained
// by none of the models (an occluding edge, an interreflection, a cast shadow's penumbra): LM
// crawls there for tens of iterations refining the wrong model. Its polish gets at most this
// many iterations and, when it runs out, the pixel is flagged kFitNotConverged as usual.
constexpr double kUnexplainedReducedChi2 = 100;
constexpr int kUnexplainedPolishIterations = 10;

// The closed-form candidates (relight/fit/profiled_fit.h) at the photometric-stereo normal; the
// best by BIC, and every other still within reach of it, polished by LM.
std::array<ModelFit, 5> fit_candidates_profiled(const PixelData& d, const FitOptions& options,
                                                std::array<bool, 5>* implausible) {
  thread_local profiled::PixelTerms terms;
  terms.reset(d.samples, d.count, d.n0, d.wo);
  std::array<profiled::Candidate, 4> candidates;
  candidates[1] = terms.lambert();
  if (options.fit_oren_nayar) candidates[2] = terms.oren_nayar();
  if (options.fit_torrance_sparrow) {
    candidates[3] = terms.torrance_sparrow(options.max_specular_albedo);
    (*implausible)[3] = candidates[3].implausible_lobe;
  }
  std::array<ModelFit, 5> fits;
  for (int k = 1; k < 4; ++k) fits[k] = to_model_fit(candidates[k], FitModel(k), d.n0, d);
  int iterations = options.max_iterations;
  // The LM polish of candidate k, normal included. The candidate is kept when the polish ends no
  // lower (it already was the minimum), and flagged not converged when the polish failed or left
  // the k_s bound.
  auto polish = [&](int k) {
    const profiled::Polished p =
        profiled::polish(FitModel(k), candidates[k], d, terms.min_roughness(), iterations);
    if (p.status == SolverStatus::kFailed || p.fit.ks > options.max_specular_albedo) {
      fits[k].status = SolverStatus::kHitIterationLimit;
      return;
    }
    if (p.fit.chi2 < candidates[k].chi2) fits[k] = to_model_fit(p.fit, FitModel(k), p.normal, d);
    fits[k].status = p.status;
  };
  int best = 0;
  for (int k = 1; k < 4; ++k) {
    if (fits[k].ok && (best == 0 || fits[k].bic < fits[best].bic)) best = k;
  }
  if (best == 0) return fits;
  const int dof = std::max(1, 3 * d.count - fits[best].k);
  if (fits[best].chi2 > kUnexplainedReducedChi2 * dof) {
    iterations = std::min(iterations, kUnexplainedPolishIterations);
  }
  const double coarse_chi2 = fits[best].chi2;
  polish(best);
  const double gain = coarse_chi2 - fits[best].chi2;
  const double reach = fits[best].bic + gain + kPolishMargin;
  for (int k = 1; k < 4; ++k) {
    if (k != best && fits[k].ok && fits[k].bic < reach) polish(k);
  }
  if (options.fit_phong) fits[4] = fit_phong(d, fits[1].x, options, implausible);
  return fits;
}

// Fits one pixel with usable samples: chooses the model, writes the map values m, counts in local.
void fit_pixel(const PixelData& d, const FitOptions& options, float* m, FitSummary& local) {
  std::array<bool, 5> implausible{};
  const std::array<ModelFit, 5> fits = options.solver == FitSolver::kProfiled
                                           ? fit_candidates_profiled(d, options, &implausible)
                                           : fit_candidates_by_lm(d, options, &implausible);
  int best = 0;
  for (int k = 1; k < 5; ++k) {
    const bool tried = k == 1 || (k == 2 && options.fit_oren_nayar) ||
                       (k == 3 && options.fit_torrance_sparrow) || (k == 4 && options.fit_phong);
    if (tried && !fits[k].ok) {
      if (implausible[k]) {
        ++local.discarded_implausible_lobes;
      } else {
        ++local.discarded_nonfinite_fits;
      }
    }
    // Strictly lower BIC needed: ties go to the simpler model (lower index).
    if (fits[k].ok && (best == 0 || fits[k].bic < fits[best].bic)) best = k;
  }
  if (best == 0) {
    m[kMapFlags] = float(kFitFailed);
    ++local.flagged;
    return;
  }
  const ModelFit& f = fits[best];
  double weight_sum = 0;
  for (int k = 1; k < 5; ++k) {
    if (fits[k].ok) weight_sum += std::exp(-0.5 * (fits[k].bic - f.bic));
  }
  for (int c = 0; c < 3; ++c) {
    m[kMapNormalX + c] = float(f.normal(c));
    m[kMapAlbedoR + c] = float(f.albedo(c));
  }
  m[kMapSigma] = float(f.sigma);
  m[kMapKs] = float(f.ks);
  m[kMapRoughness] = float(f.roughness);
  m[kMapModel] = float(best);
  m[kMapConfidence] = float(1 / weight_sum);
  const int dof = 3 * d.count - f.k;
  m[kMapResidual] = float(dof > 0 ? f.chi2 / dof : f.chi2);
  // The chosen parameters are where the solver stopped, not at a minimum.
  const bool not_converged = f.status != SolverStatus::kConverged;
  m[kMapFlags] = float(not_converged ? kFitNotConverged : 0);
  local.not_converged += not_converged;
  ++local.fitted;
  ++local.per_model[best];
}

// fit_pixel, then (FitOptions::readmit_dim_samples) again from its normal with the samples under
// the shadow threshold that it predicts dim (pixel::gather_with_dim_samples; `dim`: room for every
// valid light); the first fit stands where none was readmitted or the second finds no model.
void fit_pixel_with_dim_samples(const capture::ReflectanceField& field,
                                const capture::ValidLights& valid, int x, int y, const PixelData& d,
                                const FitOptions& options, float* m, Sample* dim,
                                FitSummary& local) {
  FitSummary first;  // Counted only when it stands.
  fit_pixel(d, options, m, first);
  const Eigen::Vector3f wo = d.wo.cast<float>();
  const auto predicted = [&](const Eigen::Vector3d& l) {
    return double(luminance(
        model_radiance(m, l.cast<float>(), wo, float(options.max_specular_albedo)).data()));
  };
  const int with_dim = m[kMapModel] != 0 ? pixel::gather_with_dim_samples(
                                               field, valid, options.normals, x, y, predicted, dim)
                                         : 0;
  if (with_dim == 0) {
    local.add(first);
    return;
  }
  // From the first fit's normal: the dim samples refine it, they do not start it again.
  PixelData again = d;
  again.samples = dim;
  again.count = with_dim;
  again.n0 = Eigen::Vector3d(m[kMapNormalX], m[kMapNormalX + 1], m[kMapNormalX + 2]).normalized();
  again.t1 = again.n0.unitOrthogonal();
  again.t2 = again.n0.cross(again.t1);
  std::array<float, kMapChannelCount> first_maps;
  std::copy_n(m, kMapChannelCount, first_maps.begin());
  FitSummary second;
  fit_pixel(again, options, m, second);
  if (m[kMapModel] == 0) {  // The first fit stands where the second finds none.
    std::copy(first_maps.begin(), first_maps.end(), m);
    second = first;
  }
  local.add(second);
}

}  // namespace

const char* to_string(FitModel model) {
  switch (model) {
    case FitModel::kNone:
      return "none";
    case FitModel::kLambert:
      return "lambert";
    case FitModel::kOrenNayar:
      return "oren-nayar";
    case FitModel::kLambertTorranceSparrow:
      return "lambert+torrance-sparrow";
    case FitModel::kLambertPhong:
      return "lambert+phong";
  }
  return "?";
}

int model_parameters(FitModel model, bool refine_normal) {
  const int k = model == FitModel::kLambert     ? kNumParams<FitModel::kLambert>
                : model == FitModel::kOrenNayar ? kNumParams<FitModel::kOrenNayar>
                                                : kNumParams<FitModel::kLambertTorranceSparrow>;
  return refine_normal ? k : k - 2;
}

const char* to_string(FitMaterials materials) {
  return materials == FitMaterials::kBasis ? "basis" : "per-pixel";
}

const char* to_string(FitSolver solver) {
  return solver == FitSolver::kProfiled ? "profiled" : "every-candidate-by-lm";
}

std::string FitOptions::validate() const {
  if (std::string e = normals.validate(); !e.empty()) return "normals: " + e;
  if (max_iterations < 1) return "max_iterations: expected >= 1";
  if (max_materials < 1) return "max_materials: expected >= 1";
  if (!(max_specular_albedo > 0)) return "max_specular_albedo: expected > 0";
  for (const double m : roughness_starts) {
    if (!(m > kMinRoughness && m < 1)) return "roughness_starts: expected values in (0.02, 1)";
  }
  if (fit_torrance_sparrow && roughness_starts.empty()) {
    return "roughness_starts: expected at least one start when fit_torrance_sparrow is on";
  }
  return {};
}

void FitTimes::add(const FitTimes& part) {
  noise += part.noise;
  normals += part.normals;
  candidates += part.candidates;
  materials += part.materials;
  shadows += part.shadows;
  writing += part.writing;
  reading += part.reading;
}

std::string FitTimes::to_string() const {
  std::ostringstream s;
  s << std::fixed << std::setprecision(2) << "noise " << noise << " s, normals " << normals
    << " s, candidate models " << candidates << " s, basis materials " << materials
    << " s, shadows " << shadows << " s, writing " << writing << " s";
  if (reading > 0) s << ", reading " << reading << " s";
  return s.str();
}

void FitSummary::add(const FitSummary& part) {
  times.add(part.times);
  pixels += part.pixels;
  fitted += part.fitted;
  flagged += part.flagged;
  empty += part.empty;
  for (int k = 0; k < 5; ++k) per_model[k] += part.per_model[k];
  discarded_nonfinite_fits += part.discarded_nonfinite_fits;
  discarded_implausible_lobes += part.discarded_implausible_lobes;
  not_converged += part.not_converged;
  material_pixels += part.material_pixels;
}

std::string FitSummary::to_string() const {
  std::ostringstream s;
  s << fitted << " of " << pixels << " pixels fitted, " << flagged << " flagged";
  if (empty > 0) s << ", " << empty << " with no signal (every sample 0, as outside a mask)";
  s << "; models:";
  for (int m = 1; m < 5; ++m) s << ' ' << relight::to_string(FitModel(m)) << '=' << per_model[m];
  s << "; " << discarded_nonfinite_fits << " non-finite fits discarded, "
    << discarded_implausible_lobes << " lobes with implausible k_s discarded; " << not_converged
    << " fitted pixels not converged (iteration limit); ";
  if (materials > 0) {
    s << materials << " basis materials (" << scene_materials << " scene materials) explain "
      << material_pixels << " fitted pixels; ";
  }
  s << seconds << " s";
  return s.str();
}

ModelMaps fit_models(const capture::ReflectanceField& field, const FitOptions& options) {
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError("fit options: " + error);
  }
  return fit_models(field, estimate_normals(field, options.normals), options);
}

ModelMaps fit_models(const capture::ReflectanceField& field, const NormalMap& normals,
                     const FitOptions& options) {
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError("fit options: " + error);
  }
  const int width = field.width(), height = field.height();
  LS_CHECK(normals.normal.width == width && normals.normal.height == height,
           "normal map is " + std::to_string(normals.normal.width) + "x" +
               std::to_string(normals.normal.height) + ", field is " + std::to_string(width) + "x" +
               std::to_string(height));
  // view_dir_per_pixel covers the frame: a band (field.first_row()) looks its rows up there.
  if (const std::string error =
          pixel::check_view_dirs(options.view_dir_per_pixel, width, field.frame_height());
      !error.empty()) {
    throw InputError("fit options: " + error);
  }
  const auto start_time = Clock::now();
  ModelMaps out;
  out.maps = Image(width, height, kMapChannelCount);
  out.maps.channel_names = model_map_channel_names();
  out.noise = options.normals.noise;
  out.noise_source = options.noise_source;
  ProgressCount rows_done(options.progress, "fit", height);
  const capture::ValidLights valid = capture::valid_lights(field);
  const NormalOptions& no = options.normals;
  std::mutex summary_mutex;
  FitSummary& summary = out.summary;
  summary.pixels = width * height;

  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    std::vector<Sample> samples(valid.index.size());
    std::vector<Sample> dim(options.readmit_dim_samples ? valid.index.size() : 0);
    FitSummary local;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        float* m = &out.maps.at(x, y, 0);
        const int flags = int(normals.flags.at(x, y, 0));
        if (flags != 0) {
          m[kMapFlags] = float(flags);
          ++((flags & kNoSignal) != 0 ? local.empty : local.flagged);
          continue;
        }
        const auto [count, saturated] =
            pixel::gather_samples(field, valid, no, x, y, samples.data());
        if (count < no.min_lights || saturated > no.max_saturated_fraction * (count + saturated)) {
          m[kMapFlags] =
              float((count < no.min_lights ? kFitFailed : 0) | (saturated > 0 ? kSaturated : 0));
          ++local.flagged;
          continue;
        }
        PixelData d;
        d.samples = samples.data();
        d.count = count;
        d.n0 = pixel::normal_at(normals, x, y);
        d.t1 = d.n0.unitOrthogonal();
        d.t2 = d.n0.cross(d.t1);
        d.refine_normal = options.refine_normal;
        d.wo = pixel::view_dir_at(options.view_dir_per_pixel,
                                  size_t(field.first_row() + y) * width + x);
        if (options.readmit_dim_samples) {
          fit_pixel_with_dim_samples(field, valid, x, y, d, options, m, dim.data(), local);
        } else {
          fit_pixel(d, options, m, local);
        }
      }
      rows_done.finished_one();
    }
    const std::lock_guard lock(summary_mutex);
    summary.add(local);
  });
  summary.times.candidates = seconds_since(start_time);
  const auto materials_start = Clock::now();
  if (options.materials == FitMaterials::kBasis) {
    fit_basis_materials(field, normals, options, out);  // Measures the shadows of its models.
  }
  summary.times.materials = seconds_since(materials_start);
  const auto shadows_start = Clock::now();
  if (out.shadows.empty()) measure_fit_shadows(field, options, field.first_row(), out);
  summary.times.shadows = seconds_since(shadows_start);
  summary.seconds = seconds_since(start_time);
  return out;
}

void FitOptions::use_noise_of(const capture::ReflectanceField& field) {
  if (!field.noise.measured) {
    noise_source = "default NoiseModel (the field carries no measured noise)";
    return;
  }
  normals.noise.a = field.noise.read_variance;
  normals.noise.b = field.noise.shot_variance_per_unit;
  noise_source = "measured" + (field.noise.method.empty() ? "" : " (" + field.noise.method + ")");
}

}  // namespace ls::relight
