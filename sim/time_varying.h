#pragma once
// Time-varying materials of the simulated world (Sun, Sunkavalli, Ramamoorthi, Belhumeur and Nayar
// 2007, "Time-Varying BRDFs"), as closed forms with per-point spatial variation of rate and onset
// over an object's own (s, t) coordinates in [0,1]^2.
//
// Every process moves a material from its `wet` endpoint (scene time -> -inf / at onset) to its
// `dry` endpoint (scene time -> inf) with one scalar weight w(time) in [0, 1] (0: wet, 1: dry):
//   paint drying, dust settling:  w = 1 - e^(-lambda t'),  t' = max(0, time - onset)   (seconds)
//   wet surface drying:           w = 1 / (1 + e^(-kappa (time - onset)))  (sigmoid; onset is its
//                                 midpoint, so w(0) = 1 / (1 + e^(kappa onset)), not exactly 0)
// and every BRDF parameter follows the same weight:
//   albedo(w)    = wet.albedo + (dry.albedo - wet.albedo) w          (a line; paint: the plane of
//                                                                     two colours, RGB per channel)
//   ks(w)        = wet.ks + (dry.ks - wet.ks) w
//   sigma_rad(w) = wet.sigma_rad + (dry.sigma_rad - wet.sigma_rad) w (Oren-Nayar roughness)
//   roughness(w) = 1 / ((1 - w) / m_wet + w / m_dry)                 (Beckmann m, harmonic)
// For paint, with w = 1 - e^(-lambda t'), these are exactly the paper's forms:
//   k_s(t) = (k_wet - k_dry) e^(-lambda t') + k_dry,
//   m(t)   = m_wet m_dry / ((m_dry - m_wet) e^(-lambda t') + m_wet).
// Dust settling, rho(tau) = (1 - T) rho_dust + T rho_d + e^(-lambda tau) rho_s with transmittance
// T(tau) = e^(-lambda tau), tau = t': `wet` is the clean glossy base (albedo rho_d, ks rho_s),
// `dry` the fully dusty surface (albedo rho_dust, ks = 0, same roughness and diffuse model; the
// dust is Lambertian): then albedo(w) = (1 - T) rho_dust + T rho_d and ks(w) = T rho_s exactly. A
// wet surface drying has no or a constant specular lobe (validate() requires wet.ks == dry.ks and
// equal roughness).
//
// Two processes whose parameters do not move monotonically between two endpoints:
//   corroding (rises and falls): the progress w = 1 - e^(-lambda t') as paint, and every
//                    parameter on the quadratic Bezier curve from wet through the control point
//                    `middle` to dry: p(w) = (1-w)^2 wet + 2 w (1-w) middle + w^2 dry (the
//                    roughness's reciprocal, as harmonic above); a middle albedo above both ends
//                    rises, then falls (the corroding metal: red 0.073 -> 0.118 -> 0.057).
//                    At w = 1/2 the material is (wet + 2 middle + dry) / 4.
//   wetting and drying (two phases): a dry surface wets at wetting_rate_per_s (kappa) from the
//                    onset, then dries at rate_per_s (lambda < kappa): its wetness
//                    h(t') = (e^(-lambda t') - e^(-kappa t')) / h_max, 0 before the onset, 1 at
//                    its peak, and w = 1 - h (so w starts dry at 1, reaches 0 fully wet, and
//                    returns to 1).
// Spatial variation scales every rate of a point alike (the stroke's rate_scale), so a point's
// process is its material's on its own clock.
//
// Spatial variation (per point (s, t) of the object):
//   uniform:         onset = onset_s, rate = rate_per_s everywhere.
//   spreading patch: onset = onset_s + |(s, t) - centre| / speed_per_s (the patch front moves
//                    outward at speed_per_s, in (s, t) units per second); points further than
//                    max_radius from the centre (when max_radius > 0) have no process: they keep
//                    the SceneMaterial's base (static).
//   stroke:          a brush stroke along s, over the band |t - band_center| <= band_half_width:
//                    onset = onset_s + s * stroke_duration_s (the brush moves along s), rate =
//                    rate_per_s * (rate_scale_at_start + (rate_scale_at_end - rate_scale_at_start)
//                    * s); points outside the band keep the base (static).
#include <Eigen/Core>
#include <string>

#include "physics/brdf.h"

namespace ls::sim {

struct SceneMaterial;  // sim/scene.h

enum class ProcessKind { kPaintDrying, kWetDrying, kDustSettling, kCorroding, kWettingDrying };
// "paint_drying", "wet_drying", "dust_settling", "corroding", "wetting_drying" (the scene-file
// names).
const char* process_kind_name(ProcessKind kind);

struct SpatialVariation {
  enum class Kind { kUniform, kSpreadingPatch, kStroke };
  Kind kind = Kind::kUniform;
  // Spreading patch.
  Eigen::Vector2d center{0.5, 0.5};  // In (s, t).
  double speed_per_s = 0.01;         // (s, t) units per second, > 0.
  double max_radius = 0.0;           // (s, t) units; 0 = the whole object.
  // Stroke.
  double stroke_duration_s = 0.0;    // Time the brush takes from s = 0 to s = 1, >= 0.
  double rate_scale_at_start = 1.0;  // Rate multiplier at s = 0, > 0.
  double rate_scale_at_end = 1.0;    // Rate multiplier at s = 1, > 0.
  double band_center = 0.5;          // Along t.
  double band_half_width = 0.5;      // Along t; 0.5 around 0.5 covers everything.
};

struct MaterialProcess {
  ProcessKind kind = ProcessKind::kPaintDrying;
  // lambda (1/s) for paint and dust; the sigmoid steepness kappa (1/s) for wet drying. > 0.
  double rate_per_s = 0.01;
  double onset_s = 0.0;  // Scene time the process starts (sigmoid midpoint for wet drying), >= 0.
  physics::brdf::Material wet;      // Endpoint at onset (dust: the clean base; wetting: fully wet).
  physics::brdf::Material dry;      // Endpoint at time -> inf (dust: albedo = dust colour, ks = 0).
  physics::brdf::Material middle;   // Corroding: the Bezier control point between wet and dry.
  double wetting_rate_per_s = 0.0;  // Wetting and drying: kappa (1/s), > rate_per_s.
  SpatialVariation spatial;

  // Empty when valid; otherwise a sentence naming the field (e.g. "dry.ks: ...").
  std::string validate() const;
};

// The true process at one point of a material: what `timefit` should recover there.
struct ProcessTruth {
  bool varying = false;  // False: a constant material, or a point outside the process's region.
  ProcessKind kind = ProcessKind::kPaintDrying;
  double rate_per_s = 0.0;      // lambda or kappa at this point (after spatial variation).
  double onset_s = 0.0;         // At this point (after spatial variation).
  physics::brdf::Material wet;  // Equal to dry (and to the base) when !varying.
  physics::brdf::Material dry;
  physics::brdf::Material middle;   // Corroding.
  double wetting_rate_per_s = 0.0;  // Wetting and drying, at this point.

  double weight(double time_s) const;  // w(time) above; 0 when !varying.
  physics::brdf::Material material(
      double time_s) const;  // blend_endpoints(wet, dry, weight(time_s));
                             // corroding: blend_through(...).
};

// The closed forms, for tests and for comparing fitted curves.
// w for `kind` at scene time `time_s` (t' = max(0, time_s - onset_s) for the exponentials);
// wetting_rate_per_s: kappa of kWettingDrying (ignored by the others).
double process_weight(ProcessKind kind, double rate_per_s, double onset_s, double time_s,
                      double wetting_rate_per_s = 0.0);
// (value_wet - value_dry) e^(-lambda t') + value_dry, t' = max(0, time_s - onset_s).
double exponential_value(double value_wet, double value_dry, double rate_per_s, double onset_s,
                         double time_s);
// m_wet m_dry / ((m_dry - m_wet) e^(-lambda t') + m_wet).
double beckmann_roughness_value(double m_wet, double m_dry, double rate_per_s, double onset_s,
                                double time_s);
// 1 / (1 + e^(-kappa (time_s - onset_s))).
double sigmoid_weight(double kappa_per_s, double onset_s, double time_s);
// Every parameter at weight w in [0, 1] (see the top of this file); models come from `wet`.
physics::brdf::Material blend_endpoints(const physics::brdf::Material& wet,
                                        const physics::brdf::Material& dry, double w);
// The quadratic Bezier from wet through the control `middle` to dry at w in [0, 1] (corroding).
physics::brdf::Material blend_through(const physics::brdf::Material& wet,
                                      const physics::brdf::Material& middle,
                                      const physics::brdf::Material& dry, double w);

// The true process at (s, t) of `material` (clamped to [0,1]^2).
ProcessTruth truth_at(const SceneMaterial& material, double s, double t);
// The material at (s, t) and scene time `time_s`; a material without a process returns its base
// (no checker or texture: those are applied by trace_camera, which knows the texture images).
physics::brdf::Material material_at(const SceneMaterial& material, double s, double t,
                                    double time_s);

}  // namespace ls::sim
