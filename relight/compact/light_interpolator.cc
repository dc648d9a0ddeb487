// LightInterpolator (directions between the LEDs) and the raw field as a CompactField
// (relight/compact/pca_field.h).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "lightstage/direction_index.h"  // angle_between
#include "lightstage/errors.h"
#include "relight/compact/pca_field.h"
#include "relight/lighting/relight.h"

namespace ls::relight {

// ---------------------------------------------------------------------------------------------
// LightInterpolator

LightInterpolator::LightInterpolator(const std::vector<capture::FieldLight>& leds,
                                     double sigma_rad) {
  for (int l = 0; l < int(leds.size()); ++l) {
    dirs_.push_back(leds[size_t(l)].dir_in_stage.normalized());
    if (leds[size_t(l)].valid) active_.push_back(l);
  }
  const int n = int(active_.size());
  if (n == 0) return;
  if (!(sigma_rad > 0)) {
    double sum = 0;
    for (int i = 0; i < n; ++i) {
      double nearest = M_PI;
      for (int j = 0; j < n; ++j) {
        if (i != j)
          nearest = std::min(nearest, angle_between(dirs_[active_[i]], dirs_[active_[j]]));
      }
      sum += nearest;
    }
    sigma_rad = n > 1 ? sum / n : 1.0;
  }
  sigma_rad_ = sigma_rad;
  cutoff_cos_ = 4 * sigma_rad < M_PI ? std::cos(4 * sigma_rad) : -1.0;
  Eigen::MatrixXd psi(n, n);
  std::vector<double> r;
  for (int m = 0; m < n; ++m) {
    double sum = 0;
    for (int i = 0; i < n; ++i) {
      // The same cut-off as weights_at, so that r(d_m) is exactly the unit vector e_m.
      if (dirs_[active_[m]].dot(dirs_[active_[i]]) < cutoff_cos_) {
        psi(m, i) = 0;
        continue;
      }
      const double a = angle_between(dirs_[active_[m]], dirs_[active_[i]]);
      psi(m, i) = std::exp(-a * a / (2 * sigma_rad * sigma_rad));
      sum += psi(m, i);
    }
    psi.row(m) /= sum;
  }
  psi_inverse_ = psi.partialPivLu().inverse();
}

void LightInterpolator::weights_at(const Eigen::Vector3d& dir, std::vector<double>& r) const {
  r.assign(dirs_.size(), 0.0);
  const int n = int(active_.size());
  if (n == 0) return;
  const Eigen::Vector3d d = dir.normalized();
  Eigen::VectorXd psi(n);
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const double c = d.dot(dirs_[active_[i]]);
    if (c < cutoff_cos_) {
      psi(i) = 0;
      continue;
    }
    const double a = angle_between(d, dirs_[active_[i]]);
    psi(i) = std::exp(-a * a / (2 * sigma_rad_ * sigma_rad_));
    sum += psi(i);
  }
  // Far from every LED: nothing stands for this direction (see the header). The normalisation
  // would otherwise blow a vanishing tail up to full weight.
  if (!(sum > 1e-12)) return;
  // Fade out where the nearest Gaussian is weak (outside the dome), so the normalisation does not
  // extend the outermost LEDs to the whole sphere.
  const double max_g = psi.maxCoeff();
  const double fade = std::min(1.0, max_g / std::exp(-0.5 * 4.0));  // Full weight within 2 sigma.
  psi *= fade / sum;
  const Eigen::VectorXd active_r = psi_inverse_.transpose() * psi;
  for (int i = 0; i < n; ++i) r[active_[i]] = active_r(i);
}

std::vector<float> LightInterpolator::led_irradiance(const LightingForModels& lights) const {
  std::vector<float> out(3 * dirs_.size(), 0.0f);
  std::vector<double> r;
  for (size_t k = 0; k < lights.dirs_in_stage.size(); ++k) {
    weights_at(lights.dirs_in_stage[k].cast<double>(), r);
    const Eigen::Vector3f& e = lights.irradiance_rgb[k];
    for (size_t l = 0; l < r.size(); ++l) {
      if (r[l] == 0) continue;
      for (int c = 0; c < 3; ++c) out[3 * l + c] += float(r[l] * e[c]);
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// RawCompactField

RawCompactField::RawCompactField(const capture::ReflectanceField& field, double sigma_rad)
    : field_(&field, [](const capture::ReflectanceField*) {}) {
  init(sigma_rad);
}

RawCompactField::RawCompactField(capture::ReflectanceField&& field, double sigma_rad)
    : field_(std::make_shared<const capture::ReflectanceField>(std::move(field))) {
  init(sigma_rad);
}

void RawCompactField::init(double sigma_rad) {
  interpolator_ = LightInterpolator(field_->lights(), sigma_rad);
}

void RawCompactField::relight_into(const LightingForModels& lights, Image& out) const {
  const std::vector<float> e = interpolator_.led_irradiance(lights);
  relight::relight_into(*field_, e, out);
}

}  // namespace ls::relight
