#pragma once
// Quantised PCA planes with interpolation between the lights: the representation of
// relight (cnr-isti-vclab) and OpenLIME's "rbf" and "bilinear" RTI types, colorspace "mrgb", held
// exactly as those files hold it, so what lightstage renders is what OpenLIME shows.
//
// Values are display-referred: the sRGB codes (0..255) of gain x the field, as the viewers show
// them (no transfer curve applied). Per pixel the samples form one vector of D = 3 x dims values,
// [d * 3 + k] (k = R, G, B), dims = the lights ("rbf") or a res x res octahedral grid of directions
// resampled from them ("bilinear"). PCA with the mean subtracted; each pixel keeps `planes`
// coefficients, each quantised to a byte with its plane's scale and bias (the 0.25% and 99.75%
// quantiles: relight's rangeQuantile 0.995), stored three planes to a JPEG (plane_j: planes
// 3j..3j+2 in R, G, B). The basis is stored as bytes too: the mean (truncated, 0..255), then each
// eigenvector as 127 + range_p x e (range_p = 127 / max |e|).
//
// Rendering under a light l (unit, x right, y up, z toward the camera), as OpenLIME's ShaderRTI:
//   W_p(l) = sum_i w_i(l) B_p[i]   (B_0 = mean byte / 255, B_p = (byte - 127) / range_p)
//   display(x) = W_0 + sum_p W_p (c_p(x) / 255 - bias_p) scale_p,   c_p = the plane's byte
// with w_i for "rbf" exp(-|L_i - l|^2 / sigma^2) normalised, those <= 0.001 dropped and the rest
// normalised again (relight's Rti::lightWeightsRbf, OpenLIME up to its AdaptiveRBF); for
// "bilinear" the bilinear weights of the four grid nodes around l's octahedral projection.
// Relighting decodes each light's display value (sRGB) and divides by the gain: field units.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "capture/field.h"
#include "relight/lighting/compact_field.h"

namespace ls::relight {

enum class PlaneInterpolation { kRbf, kBilinear };
const char* to_string(PlaneInterpolation interpolation);  // "rbf", "bilinear" (OpenLIME's type).

struct PlaneFieldOptions {
  PlaneInterpolation interpolation = PlaneInterpolation::kRbf;
  // A multiple of 3 (OpenLIME reads three a JPEG); 0: from the data (choose_plane_options).
  int planes = 0;
  double sigma = 0.125;  // RBF width in chord distance between unit directions (relight's -S).
  int resolution = 8;    // Bilinear grid (relight's -r): resolution^2 directions.
  // Choose sigma (rbf) or resolution (bilinear) from the data, and the planes when 0: relight's
  // fixed defaults (0.125 "for ~100 images", 8) suit one dome's density, not every dome's.
  bool from_data = true;
  double regularization = 0.1;  // Of the bilinear resampling (relight's -R).
  double gain = 0.0;  // Display units (white = 1) per field unit; 0: the brightest is white.
  int max_pca_pixels = 1 << 18;  // Pixels (evenly strided) the covariance is taken over.

  std::string validate() const;  // Empty when valid.
};

// What from_data chooses, and how: every 5th valid light held out of the field, the rest built
// on at most 16k evenly strided pixels, the held-out lights rendered, the 8-bit sRGB RMSE over
// them. sigma from 0.05..0.3 (then scaled by sqrt(4/5), the lights' spacing with all of them),
// resolution from 6..16; planes (when 0) the fewest, 3..30, within 0.25 dB of the best. Returns
// the options to build with (from_data off, gain resolved).
PlaneFieldOptions choose_plane_options(const capture::ReflectanceField& field,
                                       PlaneFieldOptions options);
// The same over a field in bands (`header`: its size and lights): one pass.
PlaneFieldOptions choose_plane_options(const capture::ReflectanceField& header,
                                       const capture::FieldBands& bands, PlaneFieldOptions options);

class PlaneField : public CompactField {
 public:
  PlaneField() = default;
  // Valid LEDs in front of the image plane (z > 0) take part; InputError when too few. With
  // options.from_data, choose_plane_options first.
  static PlaneField build(const capture::ReflectanceField& field, const PlaneFieldOptions& options);
  // A field in bands (`header`: its size and lights), never held whole: three passes (the choice
  // from the data, the covariance, the coefficients), the same planes as from the field whole.
  static PlaneField build(const capture::ReflectanceField& header, const capture::FieldBands& bands,
                          const PlaneFieldOptions& options);

  std::string name() const override;  // E.g. "rbf 9 planes".
  int width() const override { return width_; }
  int height() const override { return height_; }
  // The exported files' bytes per pixel when read from them (JPEG planes, info.json), else one
  // byte per plane plus the basis.
  double bytes_per_pixel() const override;
  void relight_into(const LightingForModels& lights, Image& out) const override;

  // The display value (0..1, sRGB) of every pixel under one light: OpenLIME's picture, 3 a pixel.
  void display_into(const Eigen::Vector3d& dir, std::vector<float>& rgb) const;
  // W (planes + 1) x 3, [p * 3 + k]: the basis interpolated at `dir`.
  std::vector<float> weights_at(const Eigen::Vector3d& dir) const;

  // Exactly what an OpenLIME folder holds (openlime_io.h).
  PlaneInterpolation interpolation = PlaneInterpolation::kRbf;
  int planes = 0;
  double sigma = 0.125;
  int resolution = 8;
  std::vector<Eigen::Vector3d> lights;    // rbf: the basis's directions (rounded to 3 decimals).
  std::vector<uint8_t> basis;             // (planes + 1) x dims x 3.
  std::vector<float> range, scale, bias;  // Per plane; scale and bias in 0..255 units.
  std::vector<uint8_t> codes;             // Per pixel, row-major from the top: `planes` bytes.
  double gain = 1.0;                      // Display units per field unit.
  std::uintmax_t stored_bytes = 0;        // The files' size, when read from them.

  int dims() const;  // Directions the basis is given at.
  void set_size(int width, int height) { width_ = width, height_ = height; }

 private:
  int width_ = 0, height_ = 0;
};

// lightstage export openlime: `field` into `folder` as OpenLIME reads it (info.json and
// plane_0.jpg ...; the folder is made, its files replaced). format "jpg" at `jpeg_quality` (what
// relight writes, quality 95 its default), or "png" (lossless planes; OpenLIME loads the planes
// by info.json's "format"). Returns what was written, read back.
PlaneField write_openlime(const std::filesystem::path& folder, const PlaneField& field,
                          const std::string& format = "jpg", int jpeg_quality = 95);
// InputError naming the file and the field on anything malformed or unsupported (only "rbf" and
// "bilinear" in "mrgb", planes as jpg or png, are read).
PlaneField read_openlime(const std::filesystem::path& folder);

}  // namespace ls::relight
