#include "sim/time_varying.h"

#include <algorithm>
#include <cmath>

#include "sim/scene.h"

namespace ls::sim {

namespace {

bool same(const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return (a - b).norm() <= 1e-12; }

// e^(-x) for x >= 0 without overflow worries; x may be +inf.
double decay(double rate_per_s, double elapsed_s) {
  return std::exp(-rate_per_s * std::max(0.0, elapsed_s));
}

}  // namespace

const char* process_kind_name(ProcessKind kind) {
  switch (kind) {
    case ProcessKind::kPaintDrying:
      return "paint_drying";
    case ProcessKind::kWetDrying:
      return "wet_drying";
    case ProcessKind::kDustSettling:
      return "dust_settling";
    case ProcessKind::kCorroding:
      return "corroding";
    case ProcessKind::kWettingDrying:
      return "wetting_drying";
  }
  return "?";
}

std::string MaterialProcess::validate() const {
  if (!(rate_per_s > 0) || !std::isfinite(rate_per_s)) {
    return "rate_per_s: expected a positive finite rate (1/s), got " + std::to_string(rate_per_s);
  }
  if (!(onset_s >= 0) || !std::isfinite(onset_s)) {
    return "onset_s: expected a finite time >= 0 (seconds), got " + std::to_string(onset_s);
  }
  if (std::string p = wet.validate(); !p.empty()) return "wet: " + p;
  if (std::string p = dry.validate(); !p.empty()) return "dry: " + p;
  if (wet.diffuse != dry.diffuse) return "dry.diffuse: expected the same diffuse model as wet";
  if (wet.specular != dry.specular) return "dry.specular: expected the same specular model as wet";
  if (wet.specular == physics::brdf::SpecularModel::kPhong) {
    return "wet.specular: expected none or torrance-sparrow (the processes are Torrance-Sparrow)";
  }
  if (kind == ProcessKind::kWetDrying) {
    if (!same(wet.ks, dry.ks) || wet.roughness != dry.roughness) {
      return "dry.ks: a wet surface drying has no or a constant specular lobe: expected the ks "
             "and roughness of wet";
    }
  }
  if (kind == ProcessKind::kDustSettling) {
    if (dry.ks.norm() != 0.0) return "dry.ks: a fully dusty surface is Lambertian: expected 0";
    if (wet.roughness != dry.roughness) {
      return "dry.roughness: dust settling keeps the base's roughness: expected that of wet";
    }
    if (wet.diffuse != physics::brdf::DiffuseModel::kLambert) {
      return "wet.diffuse: dust settling is a Lambertian layer over a Lambertian+glossy base: "
             "expected lambert";
    }
  }
  if (kind == ProcessKind::kCorroding) {
    if (std::string p = middle.validate(); !p.empty()) return "middle: " + p;
    if (middle.diffuse != wet.diffuse || middle.specular != wet.specular) {
      return "middle: expected the diffuse and specular models of wet";
    }
  }
  if (kind == ProcessKind::kWettingDrying &&
      (!(wetting_rate_per_s > rate_per_s) || !std::isfinite(wetting_rate_per_s))) {
    return "wetting_rate_per_s: expected a finite rate (1/s) above rate_per_s (the surface wets "
           "faster than it dries), got " +
           std::to_string(wetting_rate_per_s);
  }
  const SpatialVariation& sp = spatial;
  if (sp.kind == SpatialVariation::Kind::kSpreadingPatch) {
    if (!(sp.speed_per_s > 0) || !std::isfinite(sp.speed_per_s)) {
      return "spatial.speed_per_s: expected a positive speed ((s, t) units per second), got " +
             std::to_string(sp.speed_per_s);
    }
    if (!(sp.max_radius >= 0)) {
      return "spatial.max_radius: expected >= 0 (0: the whole object), got " +
             std::to_string(sp.max_radius);
    }
  }
  if (sp.kind == SpatialVariation::Kind::kStroke) {
    if (!(sp.stroke_duration_s >= 0) || !std::isfinite(sp.stroke_duration_s)) {
      return "spatial.stroke_duration_s: expected a finite time >= 0, got " +
             std::to_string(sp.stroke_duration_s);
    }
    if (!(sp.rate_scale_at_start > 0) || !(sp.rate_scale_at_end > 0)) {
      return "spatial.rate_scale_at_start/end: expected positive multipliers";
    }
    if (!(sp.band_half_width > 0)) {
      return "spatial.band_half_width: expected > 0, got " + std::to_string(sp.band_half_width);
    }
  }
  return "";
}

double process_weight(ProcessKind kind, double rate_per_s, double onset_s, double time_s,
                      double wetting_rate_per_s) {
  if (kind == ProcessKind::kWetDrying) return sigmoid_weight(rate_per_s, onset_s, time_s);
  if (kind == ProcessKind::kWettingDrying) {
    const double lambda = rate_per_s, kappa = wetting_rate_per_s;
    // The wetness peaks at t* = ln(kappa / lambda) / (kappa - lambda).
    const double peak = std::log(kappa / lambda) / (kappa - lambda);
    const double h_max = decay(lambda, peak) - decay(kappa, peak);
    const double h = decay(lambda, time_s - onset_s) - decay(kappa, time_s - onset_s);
    return 1.0 - std::clamp(h / h_max, 0.0, 1.0);
  }
  return 1.0 - decay(rate_per_s, time_s - onset_s);
}

double exponential_value(double value_wet, double value_dry, double rate_per_s, double onset_s,
                         double time_s) {
  return (value_wet - value_dry) * decay(rate_per_s, time_s - onset_s) + value_dry;
}

double beckmann_roughness_value(double m_wet, double m_dry, double rate_per_s, double onset_s,
                                double time_s) {
  return m_wet * m_dry / ((m_dry - m_wet) * decay(rate_per_s, time_s - onset_s) + m_wet);
}

double sigmoid_weight(double kappa_per_s, double onset_s, double time_s) {
  const double x = kappa_per_s * (time_s - onset_s);
  // Written for either sign of x so that neither branch overflows.
  if (x >= 0) return 1.0 / (1.0 + std::exp(-x));
  const double e = std::exp(x);
  return e / (1.0 + e);
}

physics::brdf::Material blend_endpoints(const physics::brdf::Material& wet,
                                        const physics::brdf::Material& dry, double w) {
  w = std::clamp(w, 0.0, 1.0);
  physics::brdf::Material m = wet;
  m.albedo = wet.albedo + (dry.albedo - wet.albedo) * w;
  m.ks = wet.ks + (dry.ks - wet.ks) * w;
  m.sigma_rad = wet.sigma_rad + (dry.sigma_rad - wet.sigma_rad) * w;
  // Harmonic in the Beckmann m: the paper's m_wet m_dry / ((m_dry - m_wet) e^(-lambda t) + m_wet).
  m.roughness = 1.0 / ((1.0 - w) / wet.roughness + w / dry.roughness);
  m.phong_exponent = wet.phong_exponent + (dry.phong_exponent - wet.phong_exponent) * w;
  return m;
}

physics::brdf::Material blend_through(const physics::brdf::Material& wet,
                                      const physics::brdf::Material& middle,
                                      const physics::brdf::Material& dry, double w) {
  w = std::clamp(w, 0.0, 1.0);
  const double a = (1 - w) * (1 - w), b = 2 * w * (1 - w), c = w * w;
  physics::brdf::Material m = wet;
  m.albedo = a * wet.albedo + b * middle.albedo + c * dry.albedo;
  m.ks = a * wet.ks + b * middle.ks + c * dry.ks;
  m.sigma_rad = a * wet.sigma_rad + b * middle.sigma_rad + c * dry.sigma_rad;
  m.roughness = 1.0 / (a / wet.roughness + b / middle.roughness + c / dry.roughness);
  m.phong_exponent = a * wet.phong_exponent + b * middle.phong_exponent + c * dry.phong_exponent;
  return m;
}

double ProcessTruth::weight(double time_s) const {
  return varying ? process_weight(kind, rate_per_s, onset_s, time_s, wetting_rate_per_s) : 0.0;
}

physics::brdf::Material ProcessTruth::material(double time_s) const {
  if (!varying) return wet;
  if (kind == ProcessKind::kCorroding) return blend_through(wet, middle, dry, weight(time_s));
  return blend_endpoints(wet, dry, weight(time_s));
}

ProcessTruth truth_at(const SceneMaterial& material, double s, double t) {
  ProcessTruth truth;
  truth.wet = truth.dry = material.base;
  if (!material.process) return truth;
  const MaterialProcess& p = *material.process;
  s = std::clamp(s, 0.0, 1.0);
  t = std::clamp(t, 0.0, 1.0);
  truth.kind = p.kind;
  truth.rate_per_s = p.rate_per_s;
  truth.onset_s = p.onset_s;
  const SpatialVariation& sp = p.spatial;
  switch (sp.kind) {
    case SpatialVariation::Kind::kUniform:
      break;
    case SpatialVariation::Kind::kSpreadingPatch: {
      const double r = (Eigen::Vector2d(s, t) - sp.center).norm();
      if (sp.max_radius > 0 && r > sp.max_radius) return truth;  // Outside the patch: static.
      truth.onset_s += r / sp.speed_per_s;
      break;
    }
    case SpatialVariation::Kind::kStroke: {
      if (std::abs(t - sp.band_center) > sp.band_half_width) return truth;  // Off the stroke.
      truth.onset_s += s * sp.stroke_duration_s;
      truth.rate_per_s *=
          sp.rate_scale_at_start + (sp.rate_scale_at_end - sp.rate_scale_at_start) * s;
      break;
    }
  }
  truth.varying = true;
  truth.wet = p.wet;
  truth.dry = p.dry;
  truth.middle = p.middle;
  truth.wetting_rate_per_s = p.wetting_rate_per_s * (truth.rate_per_s / p.rate_per_s);
  return truth;
}

physics::brdf::Material material_at(const SceneMaterial& material, double s, double t,
                                    double time_s) {
  if (!material.process) return material.base;
  return truth_at(material, s, t).material(time_s);
}

}  // namespace ls::sim
