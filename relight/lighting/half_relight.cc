#include "relight/lighting/half_relight.h"

#include <immintrin.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>

#include "lightstage/errors.h"

namespace ls::relight {

namespace {

// The half kernel below also fuses multiply-adds.
bool has_f16c() { return capture::cpu_converts_halves() && __builtin_cpu_supports("fma"); }

// One pixel's 3L values against E: lanes of 24 values (8 lights x RGB), so lane k holds channel
// k % 3, as relight.cc's kernel does.
__attribute__((target("avx2,f16c,fma"))) void shade_half(const std::uint16_t* values,
                                                         const float* irradiance, int count,
                                                         float inv_scale, float* rgb) {
  __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps(), a2 = _mm256_setzero_ps();
  int i = 0;
  const auto* h = reinterpret_cast<const __m128i*>(values);
  for (; i + 24 <= count; i += 24, h += 3) {
    a0 = _mm256_fmadd_ps(_mm256_cvtph_ps(_mm_loadu_si128(h)), _mm256_loadu_ps(irradiance + i), a0);
    a1 = _mm256_fmadd_ps(_mm256_cvtph_ps(_mm_loadu_si128(h + 1)),
                         _mm256_loadu_ps(irradiance + i + 8), a1);
    a2 = _mm256_fmadd_ps(_mm256_cvtph_ps(_mm_loadu_si128(h + 2)),
                         _mm256_loadu_ps(irradiance + i + 16), a2);
  }
  alignas(32) float lanes[24];
  _mm256_store_ps(lanes, a0);
  _mm256_store_ps(lanes + 8, a1);
  _mm256_store_ps(lanes + 16, a2);
  for (int k = 0; i + k < count; k += 8) {  // The tail (< 24 values) through 8-wide buffers.
    alignas(16) std::uint16_t halves[8] = {};
    alignas(32) float floats[8];
    const int n = std::min(8, count - i - k);
    std::copy(values + i + k, values + i + k + n, halves);
    _mm256_store_ps(floats,
                    _mm256_cvtph_ps(_mm_load_si128(reinterpret_cast<const __m128i*>(halves))));
    for (int m = 0; m < n; ++m) lanes[k + m] += floats[m] * irradiance[i + k + m];
  }
  float sum[3] = {0, 0, 0};
  for (int k = 0; k < 24; ++k) sum[k % 3] += lanes[k];
  for (int c = 0; c < 3; ++c) rgb[c] = sum[c] * inv_scale;
}

}  // namespace

std::optional<HalfField> HalfField::of(const capture::ReflectanceField& field, double max_error,
                                       double* error) {
  if (!has_f16c()) {
    if (error) *error = -1;
    return std::nullopt;
  }
  const float scale = half_scale(field);
  const double worst = half_relit_error(field, scale);
  if (error) *error = worst;
  if (worst > max_error) return std::nullopt;
  HalfField half;
  half.width_ = field.width();
  half.height_ = field.height();
  half.num_lights_ = field.num_lights();
  half.scale_ = scale;
  half.values_.resize(field.values().size());
  const std::size_t row = std::size_t(field.width()) * field.num_lights() * 3;
  tbb::parallel_for(0, field.height(), [&](int y) {
    capture::floats_to_halves(field.values().data() + y * row, row, scale,
                              half.values_.data() + y * row);
  });
  return half;
}

void HalfField::relight_into(std::span<const float> irradiance_rgb, Image& out) const {
  const int count = 3 * num_lights_;
  if (irradiance_rgb.size() != std::size_t(count)) {
    throw InputError("relight: the field has " + std::to_string(num_lights_) +
                     " lights but the weights have " + std::to_string(irradiance_rgb.size() / 3));
  }
  if (out.width != width_ || out.height != height_ || out.channels != 3) {
    out = Image(width_, height_, 3);
  }
  out.channel_names = {"R", "G", "B"};
  const float inv_scale = 1.0f / scale_;
  tbb::parallel_for(0, height_, [&](int y) {
    const std::uint16_t* row = values_.data() + std::size_t(y) * width_ * count;
    float* out_row = out.pixels.data() + std::size_t(y) * width_ * 3;
    for (int x = 0; x < width_; ++x) {
      shade_half(row + std::size_t(x) * count, irradiance_rgb.data(), count, inv_scale,
                 out_row + std::size_t(3) * x);
    }
  });
}

}  // namespace ls::relight
