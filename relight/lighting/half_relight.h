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
#include "capture/half_storage.h"
#include "lightstage/image.h"

namespace ls::relight {

// The viewer's check and scale, those of half storage in field files (capture/half_storage.h).
using capture::half_relit_error;
using capture::half_scale;

class HalfField {
 public:
  // The field in half floats when this CPU converts them in hardware (F16C, with AVX2 and FMA)
  // and half_relit_error is at most max_error; else nullopt (*error, when given, says why: the
  // error, or -1 without F16C).
  static std::optional<HalfField> of(const capture::ReflectanceField& field,
                                     double max_error = capture::kHalfRelitTolerance,
                                     double* error = nullptr);

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
