#include "relight/fit/fit.h"

#include <OpenImageIO/imageio.h>
#include <ceres/tiny_solver.h>
#include <ceres/tiny_solver_autodiff_function.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>

#include "lightstage/errors.h"
#include "relight/lighting/brdf.h"

namespace ls::relight {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kLuma[3] = {0.2126, 0.7152, 0.0722};
constexpr double kMinRoughness = 0.02;
constexpr double kMaxPhongExponent = 1e4;
constexpr const char* kFitNoiseAttribute = "lightstage:fit_noise";

struct Sample {
  Eigen::Vector3d l;  // Unit, toward the LED.
  double v[3];        // Measured R per channel.
  double inv_sigma[3];
};

struct PixelData {
  const Sample* samples = nullptr;
  int count = 0;
  Eigen::Vector3d n0, t1, t2, wo;  // PS normal, its tangents, the view direction.
  bool refine_normal = true;       // Off: the two normal angles stay 0 (zero Jacobian columns).
};

template <FitModel M>
constexpr int kNumParams = M == FitModel::kLambert     ? 5
                           : M == FitModel::kOrenNayar ? 6
                                                       : 7;

template <class T>
T sigmoid(const T& u) {
  using std::exp;
  return T(1) / (T(1) + exp(-u));
}
double logit(double p) { return std::log(p / (1 - p)); }

// Parameter vector: [normal angle a, normal angle b, sqrt(albedo) r g b, model-specific...].
template <class T>
brdf::Vec3<T> normal_from(const PixelData& d, const T* p) {
  using std::sqrt;
  if (!d.refine_normal) return d.n0.cast<T>();
  brdf::Vec3<T> n = d.n0.cast<T>() + d.t1.cast<T>() * p[0] + d.t2.cast<T>() * p[1];
  const T inv_len = T(1) / sqrt(n.dot(n));
  return n * inv_len;
}

template <FitModel M>
struct Cost {
  const PixelData* d;
  int NumResiduals() const { return 3 * d->count; }

  template <class T>
  bool operator()(const T* p, T* r) const {
    const brdf::Vec3<T> n = normal_from(*d, p);
    const brdf::Vec3<T> wo = d->wo.cast<T>();
    const T albedo[3] = {p[2] * p[2], p[3] * p[3], p[4] * p[4]};
    T sigma(0), ks(0), shape(0);
    if constexpr (M == FitModel::kOrenNayar) sigma = T(0.5 * kPi) * sigmoid(p[5]);
    if constexpr (M == FitModel::kLambertTorranceSparrow) {
      ks = p[5] * p[5];
      shape = T(kMinRoughness) + T(1 - kMinRoughness) * sigmoid(p[6]);
    }
    if constexpr (M == FitModel::kLambertPhong) {
      ks = p[5] * p[5];
      shape = T(1) + T(kMaxPhongExponent - 1) * sigmoid(p[6]);
    }
    for (int i = 0; i < d->count; ++i) {
      const Sample& s = d->samples[i];
      const auto g = brdf::Geometry<T>::from_world(n, s.l.cast<T>(), wo);
      T diffuse;
      if constexpr (M == FitModel::kOrenNayar) {
        diffuse = brdf::oren_nayar(g, sigma);
      } else {
        diffuse = brdf::lambert(g);
      }
      T specular(0);
      if constexpr (M == FitModel::kLambertTorranceSparrow) {
        specular = ks * brdf::torrance_sparrow(g, shape);
      }
      if constexpr (M == FitModel::kLambertPhong) specular = ks * brdf::phong(g, shape);
      const T cos_i = g.cos_i > T(0) ? g.cos_i : T(0);
      for (int c = 0; c < 3; ++c) {
        r[3 * i + c] = ((albedo[c] * diffuse + specular) * cos_i - T(s.v[c])) * T(s.inv_sigma[c]);
      }
    }
    return true;
  }
};

struct ModelFit {
  bool ok = false;
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
  using Function = ceres::TinySolverAutoDiffFunction<Cost<M>, Eigen::Dynamic, K>;
  const Cost<M> cost{&d};
  const Function function(cost);
  ceres::TinySolver<Function> solver;
  solver.options.max_num_iterations = max_iterations;
  Eigen::Matrix<double, K, 1> x;
  for (int i = 0; i < K; ++i) x(i) = start[i];
  solver.Solve(function, &x);

  ModelFit fit;
  fit.k = d.refine_normal ? K : K - 2;
  if (!x.allFinite()) return fit;
  // chi^2 at the returned parameters, evaluated here rather than trusted from the solver.
  thread_local std::vector<double> residuals;
  residuals.resize(size_t(cost.NumResiduals()));
  cost(x.data(), residuals.data());
  double chi2 = 0;
  for (const double r : residuals) chi2 += r * r;
  if (!std::isfinite(chi2)) return fit;
  fit.chi2 = chi2;
  fit.bic = chi2 + fit.k * std::log(double(residuals.size()));
  for (int i = 0; i < K; ++i) fit.x[i] = x(i);
  fit.normal = normal_from(d, x.data());
  fit.albedo = Eigen::Vector3d(x(2) * x(2), x(3) * x(3), x(4) * x(4));
  if constexpr (M == FitModel::kOrenNayar) fit.sigma = 0.5 * kPi * sigmoid(x(5));
  if constexpr (M == FitModel::kLambertTorranceSparrow) {
    fit.ks = x(5) * x(5);
    fit.roughness = kMinRoughness + (1 - kMinRoughness) * sigmoid(x(6));
  }
  if constexpr (M == FitModel::kLambertPhong) {
    fit.ks = x(5) * x(5);
    const double exponent = 1 + (kMaxPhongExponent - 1) * sigmoid(x(6));
    fit.roughness = std::sqrt(2 / (exponent + 2));
  }
  fit.ok = fit.normal.allFinite() && fit.albedo.allFinite() && std::isfinite(fit.sigma) &&
           std::isfinite(fit.ks) && std::isfinite(fit.roughness);
  return fit;
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

std::string FitOptions::validate() const {
  if (std::string e = normals.validate(); !e.empty()) return "normals: " + e;
  if (max_iterations < 1) return "max_iterations: expected >= 1";
  if (!(max_specular_albedo > 0)) return "max_specular_albedo: expected > 0";
  for (const double m : roughness_starts) {
    if (!(m > kMinRoughness && m < 1)) return "roughness_starts: expected values in (0.02, 1)";
  }
  if (fit_torrance_sparrow && roughness_starts.empty()) {
    return "roughness_starts: expected at least one start when fit_torrance_sparrow is on";
  }
  return {};
}

std::string FitSummary::to_string() const {
  std::ostringstream s;
  s << fitted << " of " << pixels << " pixels fitted, " << flagged << " flagged; models:";
  for (int m = 1; m < 5; ++m) s << ' ' << relight::to_string(FitModel(m)) << '=' << per_model[m];
  s << "; " << discarded_nonfinite_fits << " non-finite fits discarded, "
    << discarded_implausible_lobes << " lobes with implausible k_s discarded; " << seconds << " s";
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
  if (!options.view_dir_per_pixel.empty() &&
      options.view_dir_per_pixel.size() != size_t(width) * height) {
    throw InputError("fit options: view_dir_per_pixel: expected " +
                     std::to_string(size_t(width) * height) + " directions, got " +
                     std::to_string(options.view_dir_per_pixel.size()));
  }
  const auto start_time = std::chrono::steady_clock::now();
  ModelMaps out;
  out.maps = Image(width, height, kMapChannelCount);
  out.maps.channel_names = model_map_channel_names();
  out.noise = options.normals.noise;
  out.noise_source = options.noise_source;
  std::atomic<long> rows_done{0};
  const capture::ValidLights valid = capture::valid_lights(field);
  const std::vector<int>& light_index = valid.index;
  const std::vector<Eigen::Vector3d>& dirs = valid.dirs_in_stage;
  const NormalOptions& no = options.normals;
  std::mutex summary_mutex;
  FitSummary& summary = out.summary;
  summary.pixels = width * height;

  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    std::vector<Sample> samples(dirs.size());
    FitSummary local;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        float* m = &out.maps.at(x, y, 0);
        int flags = int(normals.flags.at(x, y, 0));
        if (flags != 0) {
          m[kMapFlags] = float(flags);
          ++local.flagged;
          continue;
        }
        // Samples above the shadow threshold, as in estimate_normals.
        const float* px = field.pixel(x, y);
        double y_max = 0;
        for (const int l : light_index) {
          const float* v = px + 3 * l;
          y_max = std::max(y_max, kLuma[0] * v[0] + kLuma[1] * v[1] + kLuma[2] * v[2]);
        }
        const double threshold =
            std::max(no.shadow_sigmas * std::sqrt(no.noise.a), no.shadow_fraction * y_max);
        int count = 0;
        int saturated = 0;
        for (size_t i = 0; i < dirs.size(); ++i) {
          const float* v = px + 3 * light_index[i];
          if (capture::is_saturated(field.lights()[light_index[i]], v)) {
            ++saturated;  // A lower bound, not a measurement.
            continue;
          }
          const double lum = kLuma[0] * v[0] + kLuma[1] * v[1] + kLuma[2] * v[2];
          if (!(lum > threshold) || !std::isfinite(lum)) continue;
          Sample& s = samples[count++];
          s.l = capture::light_dir_at(field, light_index[i], x, y);  // Per pixel for near LEDs.
          for (int c = 0; c < 3; ++c) {
            s.v[c] = v[c];
            s.inv_sigma[c] = 1 / std::sqrt(no.noise.variance(v[c]));
          }
        }
        if (count < no.min_lights || saturated > no.max_saturated_fraction * (count + saturated)) {
          m[kMapFlags] =
              float((count < no.min_lights ? kFitFailed : 0) | (saturated > 0 ? kSaturated : 0));
          ++local.flagged;
          continue;
        }
        PixelData d;
        d.samples = samples.data();
        d.count = count;
        d.n0 = Eigen::Vector3d(normals.normal.at(x, y, 0), normals.normal.at(x, y, 1),
                               normals.normal.at(x, y, 2))
                   .normalized();
        d.t1 = d.n0.unitOrthogonal();
        d.t2 = d.n0.cross(d.t1);
        d.refine_normal = options.refine_normal;
        d.wo = options.view_dir_per_pixel.empty()
                   ? Eigen::Vector3d(0, 0, 1)
                   : options.view_dir_per_pixel[size_t(y) * width + x].normalized();

        // Lambert start: closed-form albedo per channel with the PS normal.
        std::array<double, 7> start{};
        for (int c = 0; c < 3; ++c) {
          double sxx = 0, sxy = 0;
          for (int i = 0; i < count; ++i) {
            const double shade = std::max(0.0, d.n0.dot(samples[i].l)) / kPi;
            const double w = samples[i].inv_sigma[c] * samples[i].inv_sigma[c];
            sxx += w * shade * shade;
            sxy += w * shade * samples[i].v[c];
          }
          start[2 + c] = std::sqrt(std::max(sxx > 0 ? sxy / sxx : 0.0, 1e-4));
        }
        std::array<ModelFit, 5> fits;
        // Lobe fits thrown away for k_s > max_specular_albedo, per model (not non-finite ones).
        std::array<bool, 5> implausible{};
        fits[1] = run_fit<FitModel::kLambert>(d, start, options.max_iterations);
        if (fits[1].ok) start = fits[1].x;
        if (options.fit_oren_nayar) {
          std::array<double, 7> s = start;
          for (int c = 2; c < 5; ++c) s[c] *= 1.07;  // A(sigma) ~ 0.87 at the start sigma.
          s[5] = logit(0.42 / (0.5 * kPi));          // sigma = 0.42 rad (24 degrees).
          fits[2] = run_fit<FitModel::kOrenNayar>(d, s, options.max_iterations);
        }
        if (options.fit_torrance_sparrow) {
          for (const double m0 : options.roughness_starts) {
            std::array<double, 7> s = start;
            s[5] = std::sqrt(0.05);
            s[6] = logit((m0 - kMinRoughness) / (1 - kMinRoughness));
            ModelFit f = run_fit<FitModel::kLambertTorranceSparrow>(d, s, options.max_iterations);
            if (f.ok && f.ks > options.max_specular_albedo) {
              implausible[3] = true;
              continue;
            }
            if (f.ok && f.bic < fits[3].bic) fits[3] = f;
          }
        }
        if (options.fit_phong) {
          std::array<double, 7> s = start;
          s[5] = std::sqrt(0.05);
          s[6] = logit(49.0 / (kMaxPhongExponent - 1));  // Exponent 50.
          fits[4] = run_fit<FitModel::kLambertPhong>(d, s, options.max_iterations);
          if (fits[4].ok && fits[4].ks > options.max_specular_albedo) {
            implausible[4] = true;
            fits[4] = ModelFit{};
          }
        }
        int best = 0;
        for (int k = 1; k < 5; ++k) {
          const bool tried = k == 1 || (k == 2 && options.fit_oren_nayar) ||
                             (k == 3 && options.fit_torrance_sparrow) ||
                             (k == 4 && options.fit_phong);
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
          continue;
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
        const int dof = 3 * count - f.k;
        m[kMapResidual] = float(dof > 0 ? f.chi2 / dof : f.chi2);
        m[kMapFlags] = 0;
        ++local.fitted;
        ++local.per_model[best];
      }
      const long done = ++rows_done;
      if (options.progress) options.progress(done, height);
    }
    const std::lock_guard lock(summary_mutex);
    summary.fitted += local.fitted;
    summary.flagged += local.flagged;
    summary.discarded_nonfinite_fits += local.discarded_nonfinite_fits;
    summary.discarded_implausible_lobes += local.discarded_implausible_lobes;
    for (int k = 0; k < 5; ++k) summary.per_model[k] += local.per_model[k];
  });
  summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  return out;
}

const std::vector<std::string>& model_map_channel_names() {
  static const std::vector<std::string> names = {
      "normal.x", "normal.y",  "normal.z", "albedo.r",   "albedo.g", "albedo.b", "sigma",
      "ks",       "roughness", "model",    "confidence", "residual", "flags"};
  return names;
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

void write_model_maps(const std::filesystem::path& path, const ModelMaps& maps,
                      const ExrAttributes& attributes) {
  const Image& image = maps.maps;
  LS_CHECK(image.channels == kMapChannelCount &&
               image.pixels.size() == image.num_pixels() * kMapChannelCount,
           "model maps have " + std::to_string(image.channels) + " channels");
  const nlohmann::json noise = {{"read_variance", maps.noise.a},
                                {"shot_variance_per_unit", maps.noise.b},
                                {"source", maps.noise_source}};
  Image named = image;
  named.channel_names = model_map_channel_names();
  ExrAttributes header = attributes;
  header.emplace_back(kFitNoiseAttribute, noise.dump());
  write_exr(path, named, ExrPixelType::kFloat, header);
  const Image& src = maps.maps;
  auto preview = [&](const std::string& name, int first, int channels, auto transform) {
    Image image(src.width, src.height, channels);
    for (size_t i = 0; i < src.num_pixels(); ++i) {
      for (int c = 0; c < channels; ++c) {
        const float v = src.pixels[i * src.channels + first + c];
        image.pixels[i * channels + c] = std::isfinite(v) ? float(transform(v)) : 0.0f;
      }
    }
    std::filesystem::path out = path;
    out.replace_extension(name + ".png");
    write_png_preview(out, image);
  };
  auto identity = [](float v) { return v; };
  preview("normal", kMapNormalX, 3, [](float v) { return 0.5f + 0.5f * v; });
  preview("albedo", kMapAlbedoR, 3, identity);
  preview("sigma", kMapSigma, 1, [](float v) { return v / (0.5 * kPi); });
  preview("ks", kMapKs, 1, identity);
  preview("roughness", kMapRoughness, 1, identity);
  preview("model", kMapModel, 1, [](float v) { return v / 4; });
  preview("confidence", kMapConfidence, 1, identity);
  preview("residual", kMapResidual, 1,
          [](float v) { return std::log10(1 + std::max(v, 0.f)) / 2; });
  preview("flags", kMapFlags, 1, [](float v) { return v / 63; });  // Bits up to kSaturated (32).
}

ModelMaps read_model_maps(const std::filesystem::path& path) {
  const std::string name = path.string();
  if (!std::filesystem::exists(path)) throw InputError(name + ": file not found");
  auto in = OIIO::ImageInput::open(name);
  if (!in) throw InputError(name + ": cannot read model maps: " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  const std::vector<std::string>& names = model_map_channel_names();
  // File channel of each MapChannel (EXR stores channels sorted by name).
  std::vector<int> file_channel(kMapChannelCount, -1);
  for (int c = 0; c < kMapChannelCount; ++c) {
    for (int f = 0; f < spec.nchannels; ++f) {
      if (spec.channelnames[f] == names[c]) file_channel[c] = f;
    }
    if (file_channel[c] < 0) {
      throw InputError(name + ": channel '" + names[c] +
                       "': missing (not model maps from 'lightstage fit'?)");
    }
  }
  if (spec.nchannels != kMapChannelCount) {
    throw InputError(name + ": channels: expected " + std::to_string(int(kMapChannelCount)) +
                     " (model maps), got " + std::to_string(spec.nchannels));
  }
  if (spec.width <= 0 || spec.height <= 0) throw InputError(name + ": image has no pixels");
  Image raw(spec.width, spec.height, spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, raw.pixels.data())) {
    throw InputError(name + ": cannot read pixels (truncated or corrupt file?): " + in->geterror());
  }
  ModelMaps out;
  out.noise_source = "unknown (no '" + std::string(kFitNoiseAttribute) + "' attribute)";
  if (const OIIO::ParamValue* noise = spec.find_attribute(kFitNoiseAttribute)) {
    try {
      const nlohmann::json j = nlohmann::json::parse(noise->get_string());
      out.noise.a = j.at("read_variance").get<double>();
      out.noise.b = j.at("shot_variance_per_unit").get<double>();
      out.noise_source = j.value("source", std::string());
    } catch (const nlohmann::json::exception& e) {
      throw InputError(name + ": attribute '" + kFitNoiseAttribute +
                       "': expected {read_variance, shot_variance_per_unit, source}: " + e.what());
    }
    if (!(std::isfinite(out.noise.a) && out.noise.a >= 0 && std::isfinite(out.noise.b) &&
          out.noise.b >= 0)) {
      throw InputError(name + ": attribute '" + kFitNoiseAttribute +
                       "': expected finite non-negative variances");
    }
  }
  in->close();

  out.maps = Image(spec.width, spec.height, kMapChannelCount);
  out.maps.channel_names = names;
  for (size_t i = 0; i < raw.num_pixels(); ++i) {
    for (int c = 0; c < kMapChannelCount; ++c) {
      out.maps.pixels[i * kMapChannelCount + c] = raw.pixels[i * spec.nchannels + file_channel[c]];
    }
  }
  FitSummary& summary = out.summary;
  summary.pixels = spec.width * spec.height;
  auto fail = [&](int channel, int x, int y, const std::string& expected) {
    char where[96];
    std::snprintf(where, sizeof where, " at (%d, %d), got %.9g", x, y,
                  double(out.maps.at(x, y, channel)));
    throw InputError(name + ": channel '" + names[channel] + "': expected " + expected + where);
  };
  const double max_sigma = 0.5 * kPi + 1e-6;
  for (int y = 0; y < spec.height; ++y) {
    for (int x = 0; x < spec.width; ++x) {
      for (int c = 0; c < kMapChannelCount; ++c) {
        if (!std::isfinite(out.maps.at(x, y, c))) fail(c, x, y, "a finite value");
      }
      const float model = out.maps.at(x, y, kMapModel);
      if (!(model == std::floor(model) && model >= 0 && model <= 4)) {
        fail(kMapModel, x, y, "an integer in 0..4 (FitModel)");
      }
      const float flags = out.maps.at(x, y, kMapFlags);
      if (!(flags == std::floor(flags) && flags >= 0)) {
        fail(kMapFlags, x, y, "a non-negative integer");
      }
      if (model == 0) {
        ++summary.flagged;
        continue;
      }
      ++summary.fitted;
      ++summary.per_model[int(model)];
      const Eigen::Vector3d n(out.maps.at(x, y, kMapNormalX), out.maps.at(x, y, kMapNormalY),
                              out.maps.at(x, y, kMapNormalZ));
      if (std::abs(n.norm() - 1) > 1e-3) fail(kMapNormalX, x, y, "a unit normal (x, y, z)");
      for (int c = kMapAlbedoR; c <= kMapAlbedoB; ++c) {
        if (out.maps.at(x, y, c) < 0) fail(c, x, y, "an albedo >= 0");
      }
      const float sigma = out.maps.at(x, y, kMapSigma);
      if (!(sigma >= 0 && sigma <= max_sigma)) fail(kMapSigma, x, y, "sigma in [0, pi/2] rad");
      if (!(out.maps.at(x, y, kMapKs) >= 0)) fail(kMapKs, x, y, "k_s >= 0");
      const float roughness = out.maps.at(x, y, kMapRoughness);
      const bool has_lobe = model == float(FitModel::kLambertTorranceSparrow) ||
                            model == float(FitModel::kLambertPhong);
      if (has_lobe && !(roughness > 0 && roughness <= 1)) {
        fail(kMapRoughness, x, y, "a roughness in (0, 1] on a pixel with a specular lobe");
      }
    }
  }
  return out;
}

}  // namespace ls::relight
