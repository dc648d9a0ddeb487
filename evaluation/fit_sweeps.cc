#include "evaluation/fit_sweeps.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <random>

#include "capture/field.h"
#include "lightstage/angles.h"
#include "lightstage/errors.h"
#include "lightstage/stage.h"
#include "relight/fit/fit.h"
#include "relight/fit/normals.h"
#include "sim/noisy_field.h"
#include "sim/region_materials.h"

namespace ls::evaluation {
namespace {

using sim::kGlossy;
using sim::kMatte;
using sim::kRough;
using sim::Plane;
using sim::Scene;
using sim::SceneMaterial;
using sim::SurfaceHit;

// A fitted normal further off than this on a pixel the fit did not flag is a failure nobody was
// told about.
constexpr double kGrossErrorDeg = 30.0;
// Bounds on outputs: unit normals to this tolerance; the fit's parameter ranges
// (relight/fit/fit.h).
constexpr double kUnitTolerance = 1e-3;
constexpr double kMaxSigma = std::numbers::pi / 2 + 1e-6;
constexpr double kMaxRoughness = 1.0 + 1e-6;
// Albedo and k_s are u^2 in the fit (relight/fit/fit.h), declared >= 0 with no upper bound; values
// above kMaxPlausibleAlbedo are in bounds but implausible (a passive surface reflects at most what
// it receives) and counted separately.
constexpr double kUnbounded = std::numeric_limits<double>::max();
constexpr double kMaxPlausibleAlbedo = 1.0;

relight::FitModel region_model(int region) {
  return region == kMatte   ? relight::FitModel::kLambert
         : region == kRough ? relight::FitModel::kOrenNayar
                            : relight::FitModel::kLambertTorranceSparrow;
}

// Three spheres in a row; object index = region.
Scene three_spheres() {
  Scene scene;
  add_region_materials(scene);
  for (int r = 0; r < 3; ++r)
    scene.spheres.push_back({Eigen::Vector3d(-0.9 + 0.9 * r, 0, 0), 0.4, r});
  return scene;
}

// Three horizontal strips of one plane, normal tilted `tilt_deg` from the view toward +X (the dome
// side of the stage): coplanar, so they cast no shadows on each other. Object index = region.
Scene tilted_strips(double tilt_deg) {
  Scene scene;
  add_region_materials(scene);
  const double t = tilt_deg / kRadToDeg;
  for (int r = 0; r < 3; ++r) {
    Plane p;
    p.center = Eigen::Vector3d(0, 0.3 - 0.3 * r, 0);
    p.normal = Eigen::Vector3d(std::sin(t), 0, std::cos(t));
    // Wide enough to fill the view at any tilt up to 85 degrees.
    p.half_width = 1.6 / std::max(std::cos(t), 0.09);
    p.half_height = 0.14;
    p.material = r;
    scene.planes.push_back(p);
  }
  return scene;
}

Stage sweep_stage(int leds, const FitSweepOptions& options) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(leds, -11.5));
  stage.camera.width = options.width;
  stage.camera.height = options.height;
  stage.camera.fov_y_deg = 0.0;
  stage.camera.ortho_height_m = 0.9;
  return stage;
}

// The noise-free field R(x, l) of a scene and its surface hits.
struct IdealField {
  capture::ReflectanceField field;
  std::vector<SurfaceHit> hits;
};

IdealField render_ideal(const Stage& stage, const Scene& scene) {
  IdealField out;
  out.field = sim::render_ideal_field(stage, scene, {}, &out.hits);
  return out;
}

// Rotates every light direction by exactly `degrees` about a random axis perpendicular to it.
void perturb_directions(capture::ReflectanceField& field, double degrees, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss;
  for (capture::FieldLight& light : field.lights()) {
    const Eigen::Vector3d d = light.dir_in_stage;
    Eigen::Vector3d axis(gauss(rng), gauss(rng), gauss(rng));
    axis = (axis - axis.dot(d) * d).normalized();
    const double a = degrees / kRadToDeg;
    light.dir_in_stage = (std::cos(a) * d + std::sin(a) * axis.cross(d)).normalized();
  }
}

// A wall beside every surface pixel: lights whose azimuth about the true normal falls in a wedge of
// `fraction` * 360 degrees (random orientation per pixel) are shadowed, whatever their elevation.
void shadow_wedges(capture::ReflectanceField& field, const std::vector<SurfaceHit>& hits,
                   double fraction, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 2 * std::numbers::pi);
  for (const SurfaceHit& h : hits) {
    if (!h.hit) continue;
    const Eigen::Vector3d n = h.normal;
    const Eigen::Vector3d t1 =
        (std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY())
            .cross(n)
            .normalized();
    const Eigen::Vector3d t2 = n.cross(t1);
    const double start = uniform(rng);
    float* px = field.pixel(h.pixel_x, h.pixel_y);
    for (int l = 0; l < field.num_lights(); ++l) {
      const Eigen::Vector3d& d = field.lights()[l].dir_in_stage;
      const double azimuth = std::fmod(
          std::atan2(d.dot(t2), d.dot(t1)) - start + 4 * std::numbers::pi, 2 * std::numbers::pi);
      if (azimuth < fraction * 2 * std::numbers::pi) std::fill_n(px + 3 * size_t(l), 3, 0.0f);
    }
  }
}

// Clips the brightest `fraction` of the positive samples at the level below them, as a camera
// whose every exposure saturated leaves a lower bound, and tells the field so (saturates_at, as
// build_field does), which lets normals and fits censor the clipped samples.
void saturate(capture::ReflectanceField& field, double fraction) {
  if (fraction <= 0) return;
  std::vector<float> positive;
  for (const float v : field.values()) {
    if (v > 0) positive.push_back(v);
  }
  if (positive.empty()) return;
  const size_t k = std::min(positive.size() - 1, size_t((1.0 - fraction) * positive.size()));
  std::nth_element(positive.begin(), positive.begin() + k, positive.end());
  const float clip = positive[k];
  for (int y = 0; y < field.height(); ++y) {
    for (int x = 0; x < field.width(); ++x) {
      float* px = field.pixel(x, y);
      for (int i = 0; i < 3 * field.num_lights(); ++i) px[i] = std::min(px[i], clip);
    }
  }
  for (capture::FieldLight& light : field.lights()) light.saturates_at.setConstant(clip);
}

void kill_leds(capture::ReflectanceField& field, double fraction, uint64_t seed) {
  std::vector<int> order(field.num_lights());
  for (int l = 0; l < field.num_lights(); ++l) order[l] = l;
  std::shuffle(order.begin(), order.end(), std::mt19937_64(seed));
  const int dead = int(std::lround(fraction * field.num_lights()));
  for (int i = 0; i < dead; ++i) {
    const int l = order[i];
    field.lights()[l].valid = false;
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        float* px = field.pixel(x, y) + 3 * l;
        px[0] = px[1] = px[2] = 0.0f;
      }
    }
  }
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b), -1.0, 1.0)) * kRadToDeg;
}

std::optional<double> median(std::vector<double> v) {
  if (v.empty()) return std::nullopt;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

NormalScore score(std::vector<double> errors, int flagged, int surface) {
  NormalScore s;
  s.flagged_fraction = surface > 0 ? double(flagged) / surface : 0.0;
  if (errors.empty()) return s;
  double sum = 0;
  for (const double e : errors) sum += e;
  s.mean_deg = sum / double(errors.size());
  const size_t k = std::min(errors.size() - 1, size_t(std::ceil(0.95 * errors.size())) - 1);
  std::nth_element(errors.begin(), errors.begin() + k, errors.end());
  s.p95_deg = errors[k];
  return s;
}

bool finite_in(double v, double low, double high) {
  return std::isfinite(v) && v >= low && v <= high;
}

// Normal: unit, or exactly zero where flagged.
bool valid_normal(const Eigen::Vector3d& n, bool flagged) {
  if (!n.allFinite()) return false;
  if (flagged) return n.norm() == 0.0 || std::abs(n.norm() - 1.0) < kUnitTolerance;
  return std::abs(n.norm() - 1.0) < kUnitTolerance;
}

// Describes the first invalid pixel of a map into *first (when empty).
void note_invalid(std::string* first, const char* map, int x, int y, const std::string& what) {
  if (first->empty()) {
    *first = std::string(map) + " (" + std::to_string(x) + ", " + std::to_string(y) + "): " + what;
  }
}

std::string describe(const std::vector<std::pair<const char*, double>>& values) {
  std::string out;
  for (const auto& [name, v] : values) out += std::string(name) + "=" + std::to_string(v) + " ";
  return out;
}

int invalid_normal_outputs(const relight::NormalMap& map, const char* name, std::string* first) {
  int invalid = 0;
  for (int y = 0; y < map.flags.height; ++y) {
    for (int x = 0; x < map.flags.width; ++x) {
      const float flags = map.flags.at(x, y, 0);
      const bool flagged = flags != 0;
      const Eigen::Vector3d n(map.normal.at(x, y, 0), map.normal.at(x, y, 1),
                              map.normal.at(x, y, 2));
      bool ok = finite_in(flags, 0, 255) && valid_normal(n, flagged) &&
                finite_in(map.confidence.at(x, y, 0), 0, 1);
      for (int c = 0; c < 3; ++c) ok = ok && finite_in(map.albedo.at(x, y, c), 0, kUnbounded);
      if (!ok) {
        note_invalid(first, name, x, y,
                     describe({{"flags", flags},
                               {"|n|", n.norm()},
                               {"confidence", map.confidence.at(x, y, 0)},
                               {"albedo.r", map.albedo.at(x, y, 0)},
                               {"albedo.g", map.albedo.at(x, y, 1)},
                               {"albedo.b", map.albedo.at(x, y, 2)}}));
      }
      invalid += !ok;
    }
  }
  return invalid;
}

int invalid_fit_outputs(const relight::ModelMaps& maps, std::string* first) {
  using namespace relight;
  int invalid = 0;
  for (int y = 0; y < maps.maps.height; ++y) {
    for (int x = 0; x < maps.maps.width; ++x) {
      const auto at = [&](MapChannel c) { return double(maps.at(x, y, c)); };
      const double model = at(kMapModel);
      const bool none = model == double(int(FitModel::kNone));
      bool ok = finite_in(model, 0, 4) && model == std::round(model);
      ok = ok && valid_normal({at(kMapNormalX), at(kMapNormalY), at(kMapNormalZ)}, none);
      for (int c = 0; c < 3; ++c) {
        ok = ok && finite_in(at(MapChannel(kMapAlbedoR + c)), 0, kUnbounded);
      }
      ok = ok && finite_in(at(kMapSigma), 0, kMaxSigma) && finite_in(at(kMapKs), 0, kUnbounded) &&
           finite_in(at(kMapRoughness), 0, kMaxRoughness) && finite_in(at(kMapConfidence), 0, 1) &&
           finite_in(at(kMapResidual), 0, kUnbounded) && finite_in(at(kMapFlags), 0, 1023);
      for (int j = 0; j < 2; ++j) {  // Flags up to kLobeShadowed (512); materials 1-based.
        ok = ok &&
             finite_in(at(MapChannel(kMapMaterial + 2 * j)), 0, double(maps.materials.size())) &&
             finite_in(at(MapChannel(kMapMaterialWeight + 2 * j)), 0, kUnbounded);
      }
      // A pixel without a model must say why.
      ok = ok && (!none || at(kMapFlags) != 0);
      if (!ok) {
        std::vector<std::pair<const char*, double>> values;
        for (int c = 0; c < kMapChannelCount; ++c) {
          values.push_back({maps.maps.channel_names.size() > size_t(c)
                                ? maps.maps.channel_names[c].c_str()
                                : "?",
                            at(MapChannel(c))});
        }
        note_invalid(first, "fit", x, y, describe(values));
      }
      invalid += !ok;
    }
  }
  return invalid;
}

// Runs the estimators on one degraded field and scores them against the hits.
SweepPoint evaluate(const capture::ReflectanceField& field, const std::vector<SurfaceHit>& hits,
                    const relight::NoiseModel& noise) {
  using namespace relight;
  SweepPoint point;
  NormalOptions ls_options;
  ls_options.method = NormalMethod::kLeastSquares;
  ls_options.noise = noise;
  NormalOptions robust_options = ls_options;
  robust_options.method = NormalMethod::kRobust;
  FitOptions fit_options;
  fit_options.normals = robust_options;

  const auto t0 = std::chrono::steady_clock::now();
  const NormalMap ls = estimate_normals(field, ls_options);
  const auto t_ls = std::chrono::steady_clock::now();
  const NormalMap robust = estimate_normals(field, robust_options);
  const auto t1 = std::chrono::steady_clock::now();
  const ModelMaps maps = fit_models(field, robust, fit_options);
  const auto t2 = std::chrono::steady_clock::now();
  point.least_squares_seconds = std::chrono::duration<double>(t_ls - t0).count();
  point.robust_seconds = std::chrono::duration<double>(t1 - t_ls).count();
  point.fit_seconds = std::chrono::duration<double>(t2 - t1).count();
  point.fit_pixels_per_second =
      point.fit_seconds > 0 ? double(field.width()) * field.height() / point.fit_seconds : 0.0;

  std::vector<double> ls_err, robust_err, fit_err, albedo, sigma, ks, roughness;
  int ls_flagged = 0, robust_flagged = 0, fit_flagged = 0, right = 0, fitted = 0;
  for (const SurfaceHit& h : hits) {
    if (!h.hit) continue;
    ++point.surface_pixels;
    const int x = h.pixel_x, y = h.pixel_y;
    const auto normal_of = [&](const NormalMap& m) {
      return Eigen::Vector3d(m.normal.at(x, y, 0), m.normal.at(x, y, 1), m.normal.at(x, y, 2));
    };
    if (ls.flags.at(x, y, 0) != 0) {
      ++ls_flagged;
    } else {
      ls_err.push_back(angle_deg(normal_of(ls), h.normal));
    }
    if (robust.flags.at(x, y, 0) != 0) {
      ++robust_flagged;
    } else {
      robust_err.push_back(angle_deg(normal_of(robust), h.normal));
    }
    const FitModel model = maps.model(x, y);
    if (model == FitModel::kNone) {
      ++fit_flagged;
      continue;
    }
    const auto at = [&](MapChannel c) { return double(maps.at(x, y, c)); };
    const double error =
        angle_deg(Eigen::Vector3d(at(kMapNormalX), at(kMapNormalY), at(kMapNormalZ)), h.normal);
    fit_err.push_back(error);
    point.unflagged_gross_errors += error > kGrossErrorDeg;
    point.unflagged_implausible +=
        at(kMapKs) > kMaxPlausibleAlbedo ||
        std::max({at(kMapAlbedoR), at(kMapAlbedoG), at(kMapAlbedoB)}) > kMaxPlausibleAlbedo;
    ++fitted;
    if (model != region_model(h.object)) continue;
    ++right;
    const physics::brdf::Material& truth = h.material;
    for (int c = 0; c < 3; ++c) {
      albedo.push_back(std::abs(at(MapChannel(kMapAlbedoR + c)) / truth.albedo(c) - 1));
    }
    if (h.object == kRough) sigma.push_back(std::abs(at(kMapSigma) - truth.sigma_rad) * kRadToDeg);
    if (h.object == kGlossy) {
      ks.push_back(std::abs(at(kMapKs) / truth.ks(0) - 1));
      roughness.push_back(std::abs(at(kMapRoughness) / truth.roughness - 1));
    }
  }
  point.least_squares = score(std::move(ls_err), ls_flagged, point.surface_pixels);
  point.robust = score(std::move(robust_err), robust_flagged, point.surface_pixels);
  point.fit = score(std::move(fit_err), fit_flagged, point.surface_pixels);
  point.albedo_rel = median(albedo);
  point.sigma_deg = median(sigma);
  point.ks_rel = median(ks);
  point.roughness_rel = median(roughness);
  if (fitted > 0) point.model_accuracy = double(right) / fitted;
  point.invalid_outputs =
      invalid_normal_outputs(ls, "least-squares normals", &point.first_invalid) +
      invalid_normal_outputs(robust, "robust normals", &point.first_invalid) +
      invalid_fit_outputs(maps, &point.first_invalid);
  return point;
}

}  // namespace

const char* to_string(SweepAxis axis) {
  switch (axis) {
    case SweepAxis::kNoise:
      return "noise";
    case SweepAxis::kLedCount:
      return "led_count";
    case SweepAxis::kLightDirectionError:
      return "light_direction_error";
    case SweepAxis::kShadowedFraction:
      return "shadowed_fraction";
    case SweepAxis::kSaturation:
      return "saturation";
    case SweepAxis::kDeadLeds:
      return "dead_leds";
    case SweepAxis::kGrazingNormals:
      return "grazing_normals";
  }
  return "?";
}

const char* axis_label(SweepAxis axis) {
  switch (axis) {
    case SweepAxis::kNoise:
      return "noise sigma / default NoiseModel's";
    case SweepAxis::kLedCount:
      return "LEDs on the dome";
    case SweepAxis::kLightDirectionError:
      return "error of every LED direction, deg";
    case SweepAxis::kShadowedFraction:
      return "fraction of azimuths shadowed by a wall";
    case SweepAxis::kSaturation:
      return "fraction of samples clipped";
    case SweepAxis::kDeadLeds:
      return "fraction of LEDs dead";
    case SweepAxis::kGrazingNormals:
      return "angle between normal and view, deg";
  }
  return "?";
}

std::vector<double> FitSweepOptions::values(SweepAxis axis) const {
  switch (axis) {
    case SweepAxis::kNoise:
      return quick ? std::vector<double>{0.5, 2, 8} : std::vector<double>{0.5, 1, 2, 4, 8, 16};
    case SweepAxis::kLedCount:
      // 3 is below NormalOptions::min_lights (4), the minimum of every model: they all start from
      // the photometric-stereo normal and fit only pixels with min_lights lit samples.
      return quick ? std::vector<double>{3, 8, 40}
                   : std::vector<double>{3, 4, 6, 8, 12, 20, 40, 80, 150};
    case SweepAxis::kLightDirectionError:
      return quick ? std::vector<double>{0, 2, 10} : std::vector<double>{0, 0.5, 1, 2, 5, 10};
    case SweepAxis::kShadowedFraction:
      return quick ? std::vector<double>{0, 0.25, 0.75}
                   : std::vector<double>{0, 0.1, 0.25, 0.5, 0.75, 0.9};
    case SweepAxis::kSaturation:
      return quick ? std::vector<double>{0, 0.03, 0.2}
                   : std::vector<double>{0, 0.01, 0.03, 0.1, 0.2, 0.4};
    case SweepAxis::kDeadLeds:
      return quick ? std::vector<double>{0, 0.5, 0.95}
                   : std::vector<double>{0, 0.25, 0.5, 0.75, 0.9, 0.95};
    case SweepAxis::kGrazingNormals:
      return quick ? std::vector<double>{0, 60, 80}
                   : std::vector<double>{0, 30, 50, 65, 75, 80, 85};
  }
  return {};
}

std::string FitSweepOptions::validate() const {
  if (width < 3 || height < 1 || width > 4096 || height > 4096) {
    return "fit sweeps: width and height: expected 3..4096 and 1..4096 pixels, got " +
           std::to_string(width) + " x " + std::to_string(height);
  }
  if (leds < 4 || leds > 2000) {
    return "fit sweeps: leds: expected 4..2000, got " + std::to_string(leds);
  }
  if (axes.empty()) return "fit sweeps: axes: expected at least one axis";
  return {};
}

std::vector<SweepPoint> run_fit_sweeps(const FitSweepOptions& options) {
  if (const std::string error = options.validate(); !error.empty()) throw InputError(error);
  int total = 0, done = 0;
  for (const SweepAxis axis : options.axes) total += int(options.values(axis).size());
  const relight::NoiseModel base_noise;
  // The base scene at the base dome, rendered once and degraded per point.
  std::optional<IdealField> base;
  auto base_field = [&]() -> const IdealField& {
    if (!base) base = render_ideal(sweep_stage(options.leds, options), three_spheres());
    return *base;
  };
  std::vector<SweepPoint> points;
  uint64_t point_seed = options.seed;
  for (const SweepAxis axis : options.axes) {
    for (const double value : options.values(axis)) {
      ++point_seed;
      relight::NoiseModel noise = base_noise;
      SweepPoint point;
      if (axis == SweepAxis::kLedCount || axis == SweepAxis::kGrazingNormals) {
        const Stage stage =
            sweep_stage(axis == SweepAxis::kLedCount ? int(value) : options.leds, options);
        IdealField ideal = render_ideal(
            stage, axis == SweepAxis::kLedCount ? three_spheres() : tilted_strips(value));
        sim::add_sensor_noise(ideal.field, noise.as_field_noise(), point_seed);
        point = evaluate(ideal.field, ideal.hits, noise);
      } else {
        const IdealField& ideal = base_field();
        capture::ReflectanceField field = ideal.field;
        if (axis == SweepAxis::kNoise) {
          noise.a *= value * value;
          noise.b *= value * value;
        }
        // Shadows come before the noise (a shadowed sample still has read noise); dead LEDs after
        // it (their samples are zero, not data) and so does saturation (the sensor clips what it
        // measured).
        if (axis == SweepAxis::kShadowedFraction)
          shadow_wedges(field, ideal.hits, value, point_seed);
        sim::add_sensor_noise(field, noise.as_field_noise(), point_seed);
        if (axis == SweepAxis::kDeadLeds) kill_leds(field, value, point_seed);
        if (axis == SweepAxis::kSaturation) saturate(field, value);
        if (axis == SweepAxis::kLightDirectionError) perturb_directions(field, value, point_seed);
        point = evaluate(field, ideal.hits, noise);
      }
      point.axis = axis;
      point.value = value;
      points.push_back(point);
      report(options.progress, "fit sweeps", ++done, total);
    }
  }
  return points;
}

void write_fit_sweeps_csv(const std::filesystem::path& csv, const std::vector<SweepPoint>& points) {
  std::ofstream out(csv);
  if (!out) throw InputError(csv.string() + ": cannot write");
  auto cell = [&](const std::optional<double>& v) {
    out << ',';
    if (v) out << *v;
  };
  out << "axis,value,surface_pixels,"
         "ls_mean_deg,ls_p95_deg,ls_flagged,robust_mean_deg,robust_p95_deg,robust_flagged,"
         "fit_mean_deg,fit_p95_deg,fit_flagged,albedo_rel,sigma_deg,ks_rel,roughness_rel,"
         "model_accuracy,unflagged_gross_errors,unflagged_implausible,invalid_outputs,normals_s,"
         "fit_s,"
         "fit_pixels_per_s\n";
  for (const SweepPoint& p : points) {
    out << to_string(p.axis) << ',' << p.value << ',' << p.surface_pixels;
    for (const NormalScore* s : {&p.least_squares, &p.robust, &p.fit}) {
      cell(s->mean_deg);
      cell(s->p95_deg);
      out << ',' << s->flagged_fraction;
    }
    cell(p.albedo_rel);
    cell(p.sigma_deg);
    cell(p.ks_rel);
    cell(p.roughness_rel);
    cell(p.model_accuracy);
    out << ',' << p.unflagged_gross_errors << ',' << p.unflagged_implausible << ','
        << p.invalid_outputs << ',' << p.least_squares_seconds + p.robust_seconds << ','
        << p.fit_seconds << ',' << p.fit_pixels_per_second << '\n';
  }
  if (!out) throw InputError(csv.string() + ": write failed");
}

}  // namespace ls::evaluation
