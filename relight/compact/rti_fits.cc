#include "relight/compact/rti_fits.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "lightstage/errors.h"
#include "lightstage/image.h"

namespace ls::relight {

const char* to_string(RtiBasis basis) {
  switch (basis) {
    case RtiBasis::kPtm:
      return "ptm";
    case RtiBasis::kHsh2:
      return "hsh2";
    case RtiBasis::kHsh3:
      return "hsh3";
    case RtiBasis::kHsh4:
      return "hsh4";
  }
  return "?";
}

int rti_num_terms(RtiBasis basis) {
  switch (basis) {
    case RtiBasis::kPtm:
      return 6;
    case RtiBasis::kHsh2:
      return 4;
    case RtiBasis::kHsh3:
      return 9;
    case RtiBasis::kHsh4:
      return 16;
  }
  return 0;
}

void rti_basis(RtiBasis basis, const Eigen::Vector3d& dir, double* t) {
  const int n = rti_num_terms(basis);
  std::fill(t, t + n, 0.0);
  const double norm = dir.norm();
  if (!(norm > 0) || !(dir.z() > 0)) return;
  const Eigen::Vector3d d = dir / norm;
  if (basis == RtiBasis::kPtm) {
    const double u = d.x(), v = d.y();
    t[0] = u * u;
    t[1] = v * v;
    t[2] = u * v;
    t[3] = u;
    t[4] = v;
    t[5] = 1;
    return;
  }
  const double phi = std::atan2(d.y(), d.x());
  const double ct = std::min(1.0, d.z());
  const double ct2 = ct * ct;
  const double s = std::sqrt(std::max(0.0, ct - ct2));  // sqrt(cos t - cos^2 t)
  const double cp = std::cos(phi), sp = std::sin(phi);
  t[0] = 1 / std::sqrt(2 * M_PI);
  t[1] = std::sqrt(6 / M_PI) * cp * s;
  t[2] = std::sqrt(3 / (2 * M_PI)) * (-1 + 2 * ct);
  t[3] = std::sqrt(6 / M_PI) * s * sp;
  if (n > 4) {
    t[4] = std::sqrt(30 / M_PI) * std::cos(2 * phi) * (-ct + ct2);
    t[5] = std::sqrt(30 / M_PI) * cp * (-1 + 2 * ct) * s;
    t[6] = std::sqrt(5 / (2 * M_PI)) * (1 - 6 * ct + 6 * ct2);
    t[7] = std::sqrt(30 / M_PI) * (-1 + 2 * ct) * s * sp;
    t[8] = std::sqrt(30 / M_PI) * (-ct + ct2) * std::sin(2 * phi);
  }
  if (n > 9) {
    const double s3 = s * s * s;  // (cos t - cos^2 t)^1.5
    const double p = 1 - 5 * ct + 5 * ct2;
    t[9] = 2 * std::sqrt(35 / M_PI) * std::cos(3 * phi) * s3;
    t[10] = std::sqrt(210 / M_PI) * std::cos(2 * phi) * (-1 + 2 * ct) * (-ct + ct2);
    t[11] = 2 * std::sqrt(21 / M_PI) * cp * s * p;
    t[12] = std::sqrt(7 / (2 * M_PI)) * (-1 + 12 * ct - 30 * ct2 + 20 * ct2 * ct);
    t[13] = 2 * std::sqrt(21 / M_PI) * s * p * sp;
    t[14] = std::sqrt(210 / M_PI) * (-1 + 2 * ct) * (-ct + ct2) * std::sin(2 * phi);
    t[15] = 2 * std::sqrt(35 / M_PI) * s3 * std::sin(3 * phi);
  }
}

std::string RtiFitOptions::validate() const {
  if (lrgb && basis != RtiBasis::kPtm) return "lrgb: only PTM has an LRGB variant";
  if (!(min_dir_z >= 0 && min_dir_z < 1)) return "min_dir_z: expected [0, 1)";
  if (!(ridge >= 0 && ridge < 1)) return "ridge: expected [0, 1)";
  if (!(srgb_gain >= 0 && std::isfinite(srgb_gain))) return "srgb_gain: expected a gain >= 0";
  return "";
}

RtiField::RtiField(RtiBasis basis, bool lrgb, int width, int height,
                   std::vector<float> coefficients, std::vector<float> colors)
    : basis_(basis),
      lrgb_(lrgb),
      width_(width),
      height_(height),
      coefs_(std::move(coefficients)),
      colors_(std::move(colors)) {
  LS_CHECK(!lrgb || basis == RtiBasis::kPtm, "LRGB is a PTM variant");
  LS_CHECK(coefs_.size() == size_t(width) * height * coefficients_per_pixel(),
           "RtiField: " + std::to_string(coefs_.size()) + " coefficients for " +
               std::to_string(width) + "x" + std::to_string(height) + " pixels");
  LS_CHECK(!lrgb || colors_.size() == size_t(width) * height * 3, "RtiField: LRGB needs colours");
}

std::string RtiField::name() const {
  if (basis_ == RtiBasis::kPtm) return lrgb_ ? "ptm-lrgb" : "ptm-rgb";
  return to_string(basis_);
}

double RtiField::bytes_per_pixel() const { return lrgb_ ? num_terms() + 3 : 3 * num_terms(); }

RtiField RtiField::fit(const capture::ReflectanceField& field, const RtiFitOptions& options) {
  return fit(field, capture::whole_field(field), options);
}

RtiFitter::RtiFitter(const capture::ReflectanceField& field, const RtiFitOptions& options)
    : options_(options), terms_(rti_num_terms(options.basis)), width_(field.width()) {
  if (const std::string e = options.validate(); !e.empty()) {
    throw InputError(field.source + ": RTI fit options: " + e);
  }
  for (int l = 0; l < field.num_lights(); ++l) {
    const auto& light = field.lights()[l];
    if (light.valid && light.dir_in_stage.normalized().z() > options.min_dir_z) used_.push_back(l);
  }
  if (int(used_.size()) < terms_) {
    throw InputError(field.source + ": lights: " + to_string(options.basis) + " needs at least " +
                     std::to_string(terms_) + " valid LEDs in front of the image plane (z > " +
                     std::to_string(options.min_dir_z) + "), got " + std::to_string(used_.size()));
  }
  const int n = int(used_.size());
  Eigen::MatrixXd a(n, terms_);
  for (int i = 0; i < n; ++i) {
    double t[kMaxRtiTerms];
    rti_basis(options.basis, field.lights()[used_[i]].dir_in_stage, t);
    for (int j = 0; j < terms_; ++j) a(i, j) = t[j];
  }
  Eigen::MatrixXd normal = a.transpose() * a;
  normal.diagonal().array() += options.ridge * normal.diagonal().mean();
  pinv_ = normal.ldlt().solve(a.transpose()).cast<float>();  // T x n
  design_ = a.cast<float>();
}

float RtiFitter::fit_band(const capture::ReflectanceField& band, float* coefs,
                          float* colors) const {
  const int n = int(used_.size()), terms = terms_, width = width_;
  const int per_pixel = coefficients_per_pixel();
  const bool srgb = options_.srgb_gain > 0;
  const auto gain = float(options_.srgb_gain);
  std::vector<float> row_max(size_t(band.height()), 0.0f);
  tbb::parallel_for(
      tbb::blocked_range<int>(0, band.height()), [&](const tbb::blocked_range<int>& rows) {
        Eigen::MatrixXf samples(n, 3);
        Eigen::VectorXf lum(n), lum_fit(n);
        for (int y = rows.begin(); y < rows.end(); ++y) {
          for (int x = 0; x < width; ++x) {
            const float* v = band.pixel(x, y);
            for (int i = 0; i < n; ++i) {
              for (int c = 0; c < 3; ++c) samples(i, c) = v[3 * used_[i] + c];
            }
            // In field units: the default gain maps it to white.
            row_max[size_t(y)] = std::max(row_max[size_t(y)], samples.maxCoeff());
            if (srgb) samples = samples.unaryExpr([&](float s) { return srgb_encode(gain * s); });
            float* out = coefs + (size_t(y) * width + x) * per_pixel;
            if (!options_.lrgb) {
              const Eigen::MatrixXf c = pinv_ * samples;  // T x 3
              for (int ch = 0; ch < 3; ++ch) {
                for (int j = 0; j < terms; ++j) out[ch * terms + j] = c(j, ch);
              }
              continue;
            }
            // LRGB: a polynomial for the luminance, then per channel the colour that best scales
            // it.
            lum = samples.rowwise().mean();
            const Eigen::VectorXf a_lum = pinv_ * lum;
            lum_fit = design_ * a_lum;
            const float energy = lum_fit.squaredNorm();
            for (int j = 0; j < terms; ++j) out[j] = a_lum(j);
            float* color = colors + (size_t(y) * width + x) * 3;
            for (int ch = 0; ch < 3; ++ch) {
              color[ch] = energy > 1e-30f ? samples.col(ch).dot(lum_fit) / energy : 0.0f;
            }
          }
        }
      });
  return row_max.empty() ? 0.0f : *std::max_element(row_max.begin(), row_max.end());
}

RtiField RtiField::fit(const capture::ReflectanceField& field, const capture::FieldBands& bands,
                       const RtiFitOptions& options) {
  const RtiFitter fitter(field, options);
  const int width = field.width(), height = field.height();
  const size_t per_pixel = size_t(fitter.coefficients_per_pixel());
  std::vector<float> coefs(size_t(width) * height * per_pixel, 0.0f);
  std::vector<float> colors(options.lrgb ? size_t(width) * height * 3 : 0, 0.0f);
  float max_sample = 0;
  bands([&](const capture::ReflectanceField& band) {
    const size_t first = size_t(band.first_row()) * width;
    max_sample =
        std::max(max_sample, fitter.fit_band(band, coefs.data() + first * per_pixel,
                                             options.lrgb ? colors.data() + first * 3 : nullptr));
  });
  RtiField out(options.basis, options.lrgb, width, height, std::move(coefs), std::move(colors));
  out.lights_used = fitter.lights_used();
  out.max_sample_value = max_sample;
  out.set_display_gain(options.srgb_gain);
  return out;
}

float RtiField::value(const float* coef, const float* color, int c, const double* terms) const {
  const int n = num_terms();
  double v = 0;
  if (lrgb_) {
    for (int j = 0; j < n; ++j) v += coef[j] * terms[j];
    return float(v * color[c]);
  }
  for (int j = 0; j < n; ++j) v += coef[c * n + j] * terms[j];
  return float(v);
}

float RtiField::evaluate(int x, int y, int c, const Eigen::Vector3d& dir) const {
  double t[kMaxRtiTerms];
  rti_basis(basis_, dir, t);
  const size_t p = size_t(y) * width_ + x;
  const float v = value(coefs_.data() + p * coefficients_per_pixel(),
                        lrgb_ ? colors_.data() + p * 3 : nullptr, c, t);
  return display_gain_ > 0 ? float(srgb_decode(v) / display_gain_) : v;
}

// Display-referred coefficients are not linear in the light: each light's value is decoded, then
// weighed by its irradiance (a pass over the image per light).
void RtiField::relight_display_into(const LightingForModels& lights, Image& out) const {
  std::fill(out.pixels.begin(), out.pixels.end(), 0.0f);
  const int per_pixel = coefficients_per_pixel();
  for (size_t k = 0; k < lights.dirs_in_stage.size(); ++k) {
    double t[kMaxRtiTerms];
    rti_basis(basis_, lights.dirs_in_stage[k].cast<double>(), t);
    if (std::all_of(t, t + num_terms(), [](double v) { return v == 0; })) continue;  // z <= 0.
    const Eigen::Vector3f e = lights.irradiance_rgb[k] / float(display_gain_);
    tbb::parallel_for(tbb::blocked_range<int>(0, height_), [&](const tbb::blocked_range<int>& r) {
      for (int y = r.begin(); y < r.end(); ++y) {
        for (int x = 0; x < width_; ++x) {
          const size_t p = size_t(y) * width_ + x;
          const float* coef = coefs_.data() + p * per_pixel;
          const float* color = lrgb_ ? colors_.data() + p * 3 : nullptr;
          for (int c = 0; c < 3; ++c) {
            out.pixels[p * 3 + c] += e[c] * srgb_decode(value(coef, color, c, t));
          }
        }
      }
    });
  }
}

void RtiField::relight_into(const LightingForModels& lights, Image& out) const {
  if (out.width != width_ || out.height != height_ || out.channels != 3 ||
      out.pixels.size() != size_t(width_) * height_ * 3) {
    out = Image(width_, height_, 3);
  }
  out.channel_names = {"R", "G", "B"};
  if (display_gain_ > 0) {
    relight_display_into(lights, out);
    return;
  }
  const int terms = num_terms();
  // The lighting projected onto the basis once: w[c * T + j] = sum_d E_d(c) b_j(d).
  float w[3 * kMaxRtiTerms] = {};
  for (size_t k = 0; k < lights.dirs_in_stage.size(); ++k) {
    double t[kMaxRtiTerms];
    rti_basis(basis_, lights.dirs_in_stage[k].cast<double>(), t);
    for (int c = 0; c < 3; ++c) {
      for (int j = 0; j < terms; ++j) w[c * terms + j] += float(lights.irradiance_rgb[k][c] * t[j]);
    }
  }
  const int per_pixel = coefficients_per_pixel();
  float* out_pixels = out.pixels.data();
  tbb::parallel_for(tbb::blocked_range<int>(0, height_), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width_; ++x) {
        const size_t p = size_t(y) * width_ + x;
        const float* coef = coefs_.data() + p * per_pixel;
        float* o = out_pixels + p * 3;
        if (lrgb_) {
          const float* color = colors_.data() + p * 3;
          for (int c = 0; c < 3; ++c) {
            float v = 0;
            for (int j = 0; j < terms; ++j) v += coef[j] * w[c * terms + j];
            o[c] = color[c] * v;
          }
        } else {
          for (int c = 0; c < 3; ++c) {
            float v = 0;
            for (int j = 0; j < terms; ++j) v += coef[c * terms + j] * w[c * terms + j];
            o[c] = v;
          }
        }
      }
    }
  });
}

}  // namespace ls::relight
