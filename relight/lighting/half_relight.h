#pragma once
// A field's values in half floats (IEEE binary16) for interactive relighting on the CPU. A frame
// streams every value once and is bound by memory bandwidth (a 512^2 x 150-LED field is 472 MB in
// float, ~29 ms a frame on 2 cores), so half the bytes is about twice the frame rate. Values are
// scaled by a power of two so that the largest is 2^14, well inside half's range (65504) and
// exactly undone. Used where half_relit_error allows it (the viewer's check: 1e-3).
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "capture/field.h"
#include "lightstage/image.h"

namespace ls::relight {

// The power of two that brings the field's largest |value| to 2^14 (1 for an all-zero field).
float half_scale(const capture::ReflectanceField& field);

// Worst relative error of half storage (values x scale) on a sample of ~4096 pixels relit under
// equal weights: per channel |sum half(s v) / s - sum v| / sum |v|, over (pixel, channel) pairs
// whose sum |v| is at least 1e-3 of the largest (darker ones are below display precision). The
// viewer's shader sources use it too.
double half_relit_error(const capture::ReflectanceField& field, float scale);

class HalfField {
 public:
  // The field in half floats when this CPU converts them in hardware (F16C, with AVX2 and FMA)
  // and half_relit_error is at most max_error; else nullopt (*error, when given, says why: the
  // error, or -1 without F16C).
  static std::optional<HalfField> of(const capture::ReflectanceField& field,
                                     double max_error = 1e-3, double* error = nullptr);

  int width() const { return width_; }
  int height() const { return height_; }
  std::size_t bytes() const { return values_.size() * sizeof(std::uint16_t); }
  // As relight_into (relight.h): I = sum_l R_l E_l, 3 channels into `out` (resized if needed).
  // InputError unless irradiance_rgb has 3 values per light.
  void relight_into(std::span<const float> irradiance_rgb, Image& out) const;

 private:
  HalfField() = default;
  int width_ = 0, height_ = 0, num_lights_ = 0;
  float scale_ = 1;
  std::vector<std::uint16_t> values_;  // The field's layout, each value x scale_.
};

}  // namespace ls::relight
