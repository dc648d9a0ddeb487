#pragma once
// BRDF models: one implementation for rendering, simulation and fitting, templated on the scalar
// so it runs with float/double when shading and with Ceres Jets when fitting.
//
// Conventions: isotropic models depend only on three cosines, computed in the local shading frame
// (normal = +z) or from world vectors and a normal (Geometry::from_world):
//   cos_i = n.wi (wi: unit, toward the light), cos_o = n.wo (wo: unit, toward the viewer),
//   cos_io = wi.wo.
// Values are in 1/sr. The cos(theta_i) factor is NEVER inside f. Every model returns 0 when either
// direction is at or below the surface.
#include <Eigen/Core>
#include <cmath>
#include <string>

namespace ls::physics::brdf {

template <class T>
using Vec3 = Eigen::Matrix<T, 3, 1>;

inline constexpr double kPi = 3.14159265358979323846;

template <class T>
struct Geometry {
  T cos_i, cos_o, cos_io;
  static Geometry from_local(const Vec3<T>& wi, const Vec3<T>& wo) {
    return {wi.z(), wo.z(), wi.dot(wo)};
  }
  static Geometry from_world(const Vec3<T>& n, const Vec3<T>& wi, const Vec3<T>& wo) {
    return {n.dot(wi), n.dot(wo), wi.dot(wo)};
  }
  bool above() const { return cos_i > T(0) && cos_o > T(0); }
};

// Lambert: f = albedo / pi. Returns the factor multiplying albedo.
template <class T>
T lambert(const Geometry<T>& g) {
  return g.above() ? T(1.0 / kPi) : T(0);
}

// Oren-Nayar (the "qualitative" model, Oren & Nayar 1994), sigma = std. dev. of facet slope angle
// in radians, valid [0, pi/2]. f = albedo/pi * (A + B * max(0, cos(phi_i - phi_o)) * sin(alpha)
// tan(beta)) with alpha = max(theta_i, theta_o), beta = min. The product max(0, cos dphi)
// sin(alpha) tan(beta) equals max(0, wi.wo - cos_i cos_o) / max(cos_i, cos_o): no angles, no
// division by sin. Returns the factor multiplying albedo.
// A(sigma): with the B term absent (light and view a right angle apart in azimuth) Oren-Nayar is
// Lambert with albedo * A(sigma), the albedo a render of it mostly sees.
template <class T>
T oren_nayar_a(const T& sigma) {
  const T s2 = sigma * sigma;
  return T(1) - T(0.5) * s2 / (s2 + T(0.33));
}
// dA/dsigma = -0.33 sigma / (sigma^2 + 0.33)^2.
template <class T>
T oren_nayar_a_slope(const T& sigma) {
  const T d = sigma * sigma + T(0.33);
  return T(-0.33) * sigma / (d * d);
}
template <class T>
T oren_nayar(const Geometry<T>& g, const T& sigma) {
  if (!g.above()) return T(0);
  const T s2 = sigma * sigma;
  const T a = oren_nayar_a(sigma);
  const T b = T(0.45) * s2 / (s2 + T(0.09));
  T azimuthal = g.cos_io - g.cos_i * g.cos_o;
  if (azimuthal < T(0)) azimuthal = T(0);
  const T cos_max = g.cos_i > g.cos_o ? g.cos_i : g.cos_o;
  return (a + b * azimuthal / cos_max) * T(1.0 / kPi);
}

// Torrance-Sparrow specular lobe with a Beckmann facet distribution (roughness m = RMS facet slope,
// valid (0, 1]) and the V-cavity shadowing term G. Fresnel is folded into k_s (constant).
// f = D(h) G / (4 cos_i cos_o). Returns the factor multiplying k_s.
//
// torrance_sparrow_half takes the half vector's normal-independent parts (cos_i, cos_o above 0):
// inv_len = 1 / |wi + wo| and cos_oh = wo.h = (1 + cos_io) inv_len. A fit that moves the normal
// computes them once per sample (as doubles, C) and only the cosines to the normal per step (T).
template <class T, class C>
T torrance_sparrow_half(const T& cos_i, const T& cos_o, const C& inv_len, const C& cos_oh,
                        const T& roughness) {
  using std::exp;
  const T cos_h = (cos_i + cos_o) * inv_len;  // n.h
  if (!(cos_h > T(0))) return T(0);
  const T cos_h2 = cos_h * cos_h;
  const T m2 = roughness * roughness;
  const T tan_h2 = (T(1) - cos_h2) / cos_h2;
  const T d = exp(-tan_h2 / m2) / (T(kPi) * m2 * cos_h2 * cos_h2);
  T gterm = T(1);
  const T g_o = T(2) * cos_h * cos_o / cos_oh;
  const T g_i = T(2) * cos_h * cos_i / cos_oh;
  if (g_o < gterm) gterm = g_o;
  if (g_i < gterm) gterm = g_i;
  return d * gterm / (T(4) * cos_i * cos_o);
}

template <class T>
T torrance_sparrow(const Geometry<T>& g, const T& roughness) {
  using std::sqrt;
  if (!g.above()) return T(0);
  // |wi + wo|^2 = 2 + 2 cos_io; h = (wi + wo)/|wi + wo|.
  const T len2 = T(2) + T(2) * g.cos_io;
  if (!(len2 > T(1e-12))) return T(0);
  const T inv_len = T(1) / sqrt(len2);
  return torrance_sparrow_half(g.cos_i, g.cos_o, inv_len, (T(1) + g.cos_io) * inv_len, roughness);
}

// Energy-normalised modified Phong (Lafortune & Willems 1994): f = (n+2)/(2 pi) cos^n(alpha),
// alpha between wo and wi mirrored about the normal; cos(alpha) = 2 cos_i cos_o - cos_io.
// exponent valid [1, 10^4]. Returns the factor multiplying k_s.
template <class T>
T phong(const Geometry<T>& g, const T& exponent) {
  using std::pow;
  if (!g.above()) return T(0);
  const T cos_alpha = T(2) * g.cos_i * g.cos_o - g.cos_io;
  if (!(cos_alpha > T(0))) return T(0);
  return (exponent + T(2)) * T(1.0 / (2.0 * kPi)) * pow(cos_alpha, exponent);
}

enum class DiffuseModel { kLambert, kOrenNayar };
enum class SpecularModel { kNone, kTorranceSparrow, kPhong };

// A material: a diffuse lobe plus an optional specular lobe. The nested family used by model
// choice is Lambert < Oren-Nayar < (Lambert|Oren-Nayar) + Torrance-Sparrow.
struct Material {
  DiffuseModel diffuse = DiffuseModel::kLambert;
  Eigen::Vector3d albedo{0.5, 0.5, 0.5};  // Diffuse albedo per channel, [0, 1].
  double sigma_rad = 0.0;                 // Oren-Nayar roughness, [0, pi/2].
  SpecularModel specular = SpecularModel::kNone;
  Eigen::Vector3d ks{0, 0, 0};  // Specular albedo per channel, >= 0.
  double roughness = 0.2;       // Torrance-Sparrow Beckmann m, (0, 1].
  double phong_exponent = 50;   // Phong n, [1, 1e4].

  // Empty when valid; otherwise a sentence naming the parameter and its valid range.
  std::string validate() const;
};

// RGB BRDF value in 1/sr (cos theta_i not included).
template <class T>
Vec3<T> eval(const Material& m, const Geometry<T>& g) {
  const T diffuse =
      m.diffuse == DiffuseModel::kOrenNayar ? oren_nayar(g, T(m.sigma_rad)) : lambert(g);
  Vec3<T> f = m.albedo.cast<T>() * diffuse;
  if (m.specular == SpecularModel::kTorranceSparrow) {
    f += m.ks.cast<T>() * torrance_sparrow(g, T(m.roughness));
  } else if (m.specular == SpecularModel::kPhong) {
    f += m.ks.cast<T>() * phong(g, T(m.phong_exponent));
  }
  return f;
}

}  // namespace ls::physics::brdf
