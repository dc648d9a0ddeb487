#pragma once
// The RTI classics as CompactFields: polynomial texture maps (PTM, Malzbender et al.
// 2001) and hemispherical harmonics (HSH, Gautron et al. 2004, as RTIViewer evaluates them), fitted
// per pixel by linear least squares. The design matrix depends only on the light directions, so
// its pseudo-inverse (T x n, T = 4..16 terms) is computed once and applied to every pixel.
//
// Frame: RTI's light frame is the camera's (x right, y up in the image, z toward the camera), which
// is the stage frame (DESIGN.md: camera on +Z, +Y up). Both bases live on the hemisphere z > 0
// facing the camera; LEDs at or behind the image plane (z <= min_dir_z) are left out of the fit,
// and light from there contributes nothing when relighting (reported by the callers).
//
// Values are field units (radiance per unit LED irradiance), or display-referred: the sRGB codes
// (white = 1) of gain x field units, which is what RTIViewer, relight and OpenLIME show (they
// apply no transfer curve). A fit in those codes is what they show best: fitted in linear units a
// polynomial's error lands where the eye sees it least (2-3 dB worse in 8-bit sRGB PSNR). rti_io
// converts to the 8-bit file formats.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "capture/field.h"
#include "relight/lighting/compact_field.h"

namespace ls::relight {

enum class RtiBasis { kPtm, kHsh2, kHsh3, kHsh4 };
const char* to_string(RtiBasis basis);  // "ptm", "hsh2", "hsh3", "hsh4".
int rti_num_terms(RtiBasis basis);      // 6, 4, 9, 16.
inline constexpr int kMaxRtiTerms = 16;

// The basis functions at a unit light direction:
//  * PTM, in the file's coefficient order: u^2, v^2, u v, u, v, 1 with (u, v) = (x, y).
//  * HSH of order 2..4 (4, 9, 16 terms) in RTIViewer's order and normalisation, with
//    theta = acos(z), phi = atan2(y, x).
// All terms are 0 for z <= 0 (outside the hemisphere).
void rti_basis(RtiBasis basis, const Eigen::Vector3d& dir, double* terms);

struct RtiFitOptions {
  RtiBasis basis = RtiBasis::kHsh3;
  bool lrgb = false;        // PTM only: one luminance polynomial and an RGB colour per pixel.
  double min_dir_z = 0.02;  // LEDs with dir.z at or below this are left out of the fit.
  // Tikhonov term relative to the mean diagonal of A^T A: keeps the solve stable when few LEDs
  // sample the grazing directions the high HSH orders vary most at.
  double ridge = 1e-6;
  // > 0: fit the display-referred values srgb_encode(srgb_gain * v) (white = 1), which is what the
  // RTI viewers show a file's values as (RtiField::display_gain); 0: linear field units.
  double srgb_gain = 0.0;

  std::string validate() const;  // Empty when valid.
};

class RtiField : public CompactField {
 public:
  RtiField() = default;
  // From coefficients in field units. RGB: per pixel 3 x T, [c * T + j]. LRGB (PTM only): per pixel
  // T luminance coefficients in `coefficients` and 3 colour factors in `colors`:
  // value_c(d) = colors_c * sum_j lum_j b_j(d).
  RtiField(RtiBasis basis, bool lrgb, int width, int height, std::vector<float> coefficients,
           std::vector<float> colors = {});

  static RtiField fit(const capture::ReflectanceField& field, const RtiFitOptions& options);
  // The same over a field visited in bands (capture::FieldBands; a field larger than memory):
  // `header` has its size and lights. The coefficients of the whole field, bit for bit.
  static RtiField fit(const capture::ReflectanceField& header, const capture::FieldBands& bands,
                      const RtiFitOptions& options);

  std::string name() const override;
  int width() const override { return width_; }
  int height() const override { return height_; }
  // As stored in the 8-bit formats: one byte per coefficient (PTM RGB 18, LRGB 9, HSH 3 T).
  double bytes_per_pixel() const override;
  void relight_into(const LightingForModels& lights, Image& out) const override;

  RtiBasis basis() const { return basis_; }
  bool lrgb() const { return lrgb_; }
  int num_terms() const { return rti_num_terms(basis_); }
  int coefficients_per_pixel() const { return lrgb_ ? num_terms() : 3 * num_terms(); }
  const std::vector<float>& coefficients() const { return coefs_; }
  const std::vector<float>& colors() const { return colors_; }
  // Value of pixel (x, y), channel c, under a unit light from dir (field units).
  float evaluate(int x, int y, int c, const Eigen::Vector3d& dir) const;
  // > 0: the coefficients are display-referred, sRGB codes of this many display units (white = 1)
  // per field unit; relighting decodes each light's value before adding it up. 0: linear.
  double display_gain() const { return display_gain_; }
  void set_display_gain(double gain) { display_gain_ = gain; }

  int lights_used = 0;         // LEDs the fit used (in the hemisphere, valid).
  float max_sample_value = 0;  // Largest fitted sample: the default export gain maps it to white.

 private:
  RtiBasis basis_ = RtiBasis::kHsh3;
  bool lrgb_ = false;
  int width_ = 0, height_ = 0;
  std::vector<float> coefs_;
  std::vector<float> colors_;
  double display_gain_ = 0.0;

  // The value of one pixel's channel c from the basis at a light (display or field units).
  float value(const float* coef, const float* color, int c, const double* terms) const;
  void relight_display_into(const LightingForModels& lights, Image& out) const;
};

// RtiField::fit a band at a time into the caller's buffers, for a field larger than memory whose
// coefficients go to disk as they are fitted.
class RtiFitter {
 public:
  // The field's lights; InputError as RtiField::fit for bad options or too few lights.
  RtiFitter(const capture::ReflectanceField& field, const RtiFitOptions& options);
  int lights_used() const { return int(used_.size()); }
  int coefficients_per_pixel() const { return options_.lrgb ? terms_ : 3 * terms_; }
  // The band's coefficients (and LRGB colours, 3 a pixel) into `coefs` (`colors`), its rows from
  // 0; returns its largest sample.
  float fit_band(const capture::ReflectanceField& band, float* coefs, float* colors) const;

 private:
  RtiFitOptions options_;
  int terms_, width_;
  std::vector<int> used_;   // The lights fitted.
  Eigen::MatrixXf pinv_;    // T x used: the ridge-regularised least-squares solve.
  Eigen::MatrixXf design_;  // used x T: the basis at the lights.
};

}  // namespace ls::relight
