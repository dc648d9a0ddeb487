#include "physics/brdf.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <vector>

namespace {

using ls::physics::brdf::Geometry;
using ls::physics::brdf::kPi;
using ls::physics::brdf::Vec3;

// One isotropic lobe with its parameter: f(geometry) in 1/sr, without the cosine.
struct Lobe {
  const char* name;
  double parameter;
  std::function<double(const Geometry<double>&)> f;
};

std::vector<Lobe> all_lobes() {
  std::vector<Lobe> lobes;
  lobes.push_back(
      {"lambert", 0, [](const Geometry<double>& g) { return ls::physics::brdf::lambert(g); }});
  for (double sigma : {0.0, 0.3, 1.0, kPi / 2}) {
    lobes.push_back({"oren_nayar", sigma, [sigma](const Geometry<double>& g) {
                       return ls::physics::brdf::oren_nayar(g, sigma);
                     }});
  }
  for (double m : {0.1, 0.2, 0.4, 0.7, 1.0}) {
    lobes.push_back({"torrance_sparrow", m, [m](const Geometry<double>& g) {
                       return ls::physics::brdf::torrance_sparrow(g, m);
                     }});
  }
  for (double n : {1.0, 10.0, 100.0, 1000.0}) {
    lobes.push_back(
        {"phong", n, [n](const Geometry<double>& g) { return ls::physics::brdf::phong(g, n); }});
  }
  return lobes;
}

Vec3<double> from_angles(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// Directional albedo rho(wo) = integral over the hemisphere of f(wi, wo) cos(theta_i) dwi, by
// the midpoint rule in (theta, phi) with dw = sin(theta) dtheta dphi; fine enough in theta to
// resolve a Phong lobe of exponent 1000 (about 0.03 rad wide).
double directional_albedo(const std::function<double(const Geometry<double>&)>& f,
                          const Vec3<double>& wo, int n_theta = 1200, int n_phi = 720) {
  std::vector<double> cos_phi(n_phi), sin_phi(n_phi);
  for (int j = 0; j < n_phi; ++j) {
    cos_phi[j] = std::cos(2 * kPi * (j + 0.5) / n_phi);
    sin_phi[j] = std::sin(2 * kPi * (j + 0.5) / n_phi);
  }
  double sum = 0;
  for (int i = 0; i < n_theta; ++i) {
    const double theta = 0.5 * kPi * (i + 0.5) / n_theta;
    const double cos_t = std::cos(theta), sin_t = std::sin(theta);
    double ring = 0;
    for (int j = 0; j < n_phi; ++j) {
      const Vec3<double> wi(sin_t * cos_phi[j], sin_t * sin_phi[j], cos_t);
      ring += f(Geometry<double>::from_local(wi, wo));
    }
    sum += ring * cos_t * sin_t;
  }
  return sum * (0.5 * kPi / n_theta) * (2 * kPi / n_phi);
}

TEST(BrdfTest, LambertWhiteFurnaceIsOne) {
  for (double theta_o : {0.0, 0.5, 1.2, 1.5}) {
    const double rho =
        directional_albedo([](const Geometry<double>& g) { return ls::physics::brdf::lambert(g); },
                           from_angles(theta_o, 0.3), 400, 400);
    EXPECT_NEAR(rho, 1.0, 1e-5) << theta_o;  // Midpoint rule: O(h^2) = 2.6e-6 here.
  }
}

TEST(BrdfTest, OrenNayarWithZeroSigmaIsLambert) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> angle(0.0, kPi / 2), azimuth(0.0, 2 * kPi);
  for (int i = 0; i < 1000; ++i) {
    const auto g = Geometry<double>::from_local(from_angles(angle(rng), azimuth(rng)),
                                                from_angles(angle(rng), azimuth(rng)));
    EXPECT_DOUBLE_EQ(ls::physics::brdf::oren_nayar(g, 0.0), ls::physics::brdf::lambert(g));
  }
}

// Phong is normalised so that its albedo is exactly 1 at normal incidence and less elsewhere;
// Torrance-Sparrow with G <= 1 and no Fresnel may lose energy but must not create it.
TEST(BrdfTest, SpecularDirectionalAlbedoDoesNotExceedOne) {
  for (const Lobe& lobe : all_lobes()) {
    const std::string name = lobe.name;
    if (name != "phong" && name != "torrance_sparrow") continue;
    for (double theta_o : {0.0, 0.4, 0.8, 1.2, 1.45}) {
      const double rho = directional_albedo(lobe.f, from_angles(theta_o, 0.0));
      SCOPED_TRACE(name + " parameter " + std::to_string(lobe.parameter) + " theta_o " +
                   std::to_string(theta_o));
      EXPECT_GT(rho, 0.0);
      EXPECT_LE(rho, 1.0 + 2e-3);
      if (name == "phong" && theta_o == 0.0) {
        EXPECT_NEAR(rho, 1.0, 2e-3);
      }
    }
  }
}

TEST(BrdfTest, EveryModelIsReciprocalAndZeroBelowTheHorizon) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> up(0.0, kPi / 2), down(kPi / 2, kPi),
      azimuth(0.0, 2 * kPi);
  for (const Lobe& lobe : all_lobes()) {
    SCOPED_TRACE(std::string(lobe.name) + " " + std::to_string(lobe.parameter));
    for (int i = 0; i < 500; ++i) {
      const Vec3<double> a = from_angles(up(rng), azimuth(rng));
      const Vec3<double> b = from_angles(up(rng), azimuth(rng));
      const double ab = lobe.f(Geometry<double>::from_local(a, b));
      const double ba = lobe.f(Geometry<double>::from_local(b, a));
      EXPECT_NEAR(ab, ba, 1e-12 * std::max(1.0, std::abs(ab)));
      EXPECT_TRUE(std::isfinite(ab) && ab >= 0.0);
      const Vec3<double> below = from_angles(down(rng), azimuth(rng));
      EXPECT_EQ(lobe.f(Geometry<double>::from_local(below, a)), 0.0);
      EXPECT_EQ(lobe.f(Geometry<double>::from_local(a, below)), 0.0);
    }
    // Grazing (exactly at the horizon) counts as below.
    const Vec3<double> horizon(1, 0, 0), above = from_angles(0.3, 1);
    EXPECT_EQ(lobe.f(Geometry<double>::from_local(horizon, above)), 0.0);
    EXPECT_EQ(lobe.f(Geometry<double>::from_local(above, horizon)), 0.0);
  }
}

TEST(BrdfTest, MaterialEvalSumsItsLobes) {
  ls::physics::brdf::Material m;
  m.diffuse = ls::physics::brdf::DiffuseModel::kOrenNayar;
  m.sigma_rad = 0.4;
  m.albedo = {0.2, 0.5, 0.8};
  m.specular = ls::physics::brdf::SpecularModel::kTorranceSparrow;
  m.ks = {0.1, 0.2, 0.3};
  m.roughness = 0.3;
  const auto g = Geometry<double>::from_local(from_angles(0.3, 0.1), from_angles(0.5, 2.0));
  const Vec3<double> f = ls::physics::brdf::eval(m, g);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(f[c],
                m.albedo[c] * ls::physics::brdf::oren_nayar(g, 0.4) +
                    m.ks[c] * ls::physics::brdf::torrance_sparrow(g, 0.3),
                1e-15);
  }
}

using Jet = ceres::Jet<double, 4>;

// Jet evaluation: cos_i, cos_o, cos_io and the model's parameter are the 4 variables. The value
// must match double evaluation and the derivatives must match central differences.
template <class Model>
void check_jet(const char* name, Model model, double ci, double co, double cio, double p) {
  SCOPED_TRACE(std::string(name) + " at (" + std::to_string(ci) + ", " + std::to_string(co) + ", " +
               std::to_string(cio) + ", " + std::to_string(p) + ")");
  const Geometry<Jet> gj{Jet(ci, 0), Jet(co, 1), Jet(cio, 2)};
  const Jet value = model(gj, Jet(p, 3));
  const double expected = model(Geometry<double>{ci, co, cio}, p);
  EXPECT_NEAR(value.a, expected, 1e-12 * std::max(1.0, std::abs(expected)));
  ASSERT_TRUE(std::isfinite(value.a));
  for (int k = 0; k < 4; ++k) ASSERT_TRUE(std::isfinite(value.v[k])) << "derivative " << k;
}

template <class Model>
void check_jet_derivatives(const char* name, Model model, double ci, double co, double cio,
                           double p) {
  check_jet(name, model, ci, co, cio, p);
  const Jet value = model(Geometry<Jet>{Jet(ci, 0), Jet(co, 1), Jet(cio, 2)}, Jet(p, 3));
  const double h = 1e-6;
  double x[4] = {ci, co, cio, p};
  for (int k = 0; k < 4; ++k) {
    double plus[4], minus[4];
    std::copy(x, x + 4, plus);
    std::copy(x, x + 4, minus);
    plus[k] += h;
    minus[k] -= h;
    const double fd = (model(Geometry<double>{plus[0], plus[1], plus[2]}, plus[3]) -
                       model(Geometry<double>{minus[0], minus[1], minus[2]}, minus[3])) /
                      (2 * h);
    EXPECT_NEAR(value.v[k], fd, 1e-5 * std::max(1.0, std::abs(fd))) << name << " d/dx" << k;
  }
}

TEST(BrdfTest, CeresJetEvaluationMatchesDoubleAndHasNoNanAtNormalIncidence) {
  const auto lambert = [](const auto& g, const auto&) { return ls::physics::brdf::lambert(g); };
  const auto oren_nayar = [](const auto& g, const auto& s) {
    return ls::physics::brdf::oren_nayar(g, s);
  };
  const auto ts = [](const auto& g, const auto& m) {
    return ls::physics::brdf::torrance_sparrow(g, m);
  };
  const auto phong = [](const auto& g, const auto& n) { return ls::physics::brdf::phong(g, n); };
  // A generic configuration (no kinks): wi at 30 degrees, wo at 40 degrees, 50 degrees apart in
  // azimuth.
  const Vec3<double> wi = from_angles(0.52, 0.0), wo = from_angles(0.70, 0.9);
  const double ci = wi.z(), co = wo.z(), cio = wi.dot(wo);
  check_jet_derivatives("lambert", lambert, ci, co, cio, 0.0);
  check_jet_derivatives("oren_nayar", oren_nayar, ci, co, cio, 0.5);
  check_jet_derivatives("torrance_sparrow", ts, ci, co, cio, 0.4);
  // Phong near its lobe so cos(alpha) > 0 there.
  const Vec3<double> near_mirror = from_angles(0.55, 3.2);
  check_jet_derivatives("phong", phong, ci, near_mirror.z(), wi.dot(near_mirror), 20.0);
  // Normal incidence and exitance, wi = wo = n: the degenerate case of every half-vector formula.
  for (double p : {0.05, 0.3, 1.0}) {
    check_jet("lambert", lambert, 1.0, 1.0, 1.0, p);
    check_jet("oren_nayar", oren_nayar, 1.0, 1.0, 1.0, p);
    check_jet("torrance_sparrow", ts, 1.0, 1.0, 1.0, p);
  }
  for (double n : {1.0, 50.0, 1e4}) check_jet("phong", phong, 1.0, 1.0, 1.0, n);
  // And the material as a whole, with Jet geometry.
  ls::physics::brdf::Material m;
  m.specular = ls::physics::brdf::SpecularModel::kTorranceSparrow;
  m.ks = {0.3, 0.3, 0.3};
  const Vec3<Jet> f =
      ls::physics::brdf::eval(m, Geometry<Jet>{Jet(1.0, 0), Jet(1.0, 1), Jet(1.0, 2)});
  const Vec3<double> fd = ls::physics::brdf::eval(m, Geometry<double>{1.0, 1.0, 1.0});
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(f[c].a, fd[c], 1e-12);
    EXPECT_TRUE(f[c].v.allFinite());
  }
}

TEST(BrdfTest, ValidateNamesTheParameterAndItsRange) {
  ls::physics::brdf::Material m;
  EXPECT_EQ(m.validate(), "");
  m.albedo.y() = 1.3;
  EXPECT_EQ(m.validate(), "albedo.g must be in [0, 1], got 1.3");
  m.albedo.y() = std::nan("");
  EXPECT_EQ(m.validate(), "albedo.g must be in [0, 1], got nan");
  m.albedo = {0.5, 0.5, -0.1};
  EXPECT_EQ(m.validate(), "albedo.b must be in [0, 1], got -0.1");
  m.albedo = {0.5, 0.5, 0.5};

  m.diffuse = ls::physics::brdf::DiffuseModel::kOrenNayar;
  m.sigma_rad = 2.0;
  EXPECT_EQ(m.validate(), "sigma_rad must be in [0, pi/2], got 2");
  m.sigma_rad = kPi / 2;
  EXPECT_EQ(m.validate(), "");

  m.specular = ls::physics::brdf::SpecularModel::kTorranceSparrow;
  m.roughness = 0.0;
  EXPECT_EQ(m.validate(), "roughness must be in (0, 1], got 0");
  m.roughness = 1.0;
  EXPECT_EQ(m.validate(), "");
  m.ks = {0.1, -0.2, 0.0};
  EXPECT_EQ(m.validate(), "ks.g must be in [0, inf), got -0.2");
  m.ks = {0.1, INFINITY, 0.0};
  EXPECT_NE(m.validate().find("ks must be finite"), std::string::npos) << m.validate();
  m.ks = {5.0, 0.0, 0.0};  // ks has no upper bound (Fresnel folded in, any scale).
  EXPECT_EQ(m.validate(), "");

  m.specular = ls::physics::brdf::SpecularModel::kPhong;
  m.phong_exponent = 0.5;
  EXPECT_EQ(m.validate(), "phong_exponent must be in [1, 10000], got 0.5");
  m.phong_exponent = 2e4;
  EXPECT_EQ(m.validate(), "phong_exponent must be in [1, 10000], got 20000");
  // Parameters of lobes not in use are not checked.
  m.specular = ls::physics::brdf::SpecularModel::kNone;
  m.roughness = -3;
  EXPECT_EQ(m.validate(), "");
}

}  // namespace
