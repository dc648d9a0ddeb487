#include "relight/lighting/half_relight.h"

#include <cpuid.h>
#include <immintrin.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>

#include "lightstage/errors.h"

namespace ls::relight {

namespace {

bool has_f16c() {
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (!__get_cpuid(1, &eax, &ebx, &ecx, &edx)) return false;
  constexpr unsigned kF16cBit = 1u << 29;  // CPUID.1:ECX.F16C
  return (ecx & kF16cBit) != 0 && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}

__attribute__((target("avx2,f16c"))) void to_half(const float* in, std::size_t count, float scale,
                                                  std::uint16_t* out) {
  const __m256 s = _mm256_set1_ps(scale);
  std::size_t i = 0;
  for (; i + 8 <= count; i += 8) {
    const __m128i h =
        _mm256_cvtps_ph(_mm256_mul_ps(_mm256_loadu_ps(in + i), s), _MM_FROUND_TO_NEAREST_INT);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i), h);
  }
  if (i < count) {  // The tail through an 8-wide buffer.
    alignas(32) float tail[8] = {};
    alignas(16) std::uint16_t halves[8];
    std::copy(in + i, in + count, tail);
    _mm_store_si128(
        reinterpret_cast<__m128i*>(halves),
        _mm256_cvtps_ph(_mm256_mul_ps(_mm256_load_ps(tail), s), _MM_FROUND_TO_NEAREST_INT));
    std::copy(halves, halves + (count - i), out + i);
  }
}

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

float half_scale(const capture::ReflectanceField& field) {
  float largest = 0;
  for (float v : field.values()) largest = std::max(largest, std::abs(v));
  return largest > 0 && std::isfinite(largest) ? std::ldexp(1.0f, 14 - std::ilogb(largest)) : 1.0f;
}

double half_relit_error(const capture::ReflectanceField& field, float scale) {
  const std::size_t pixels = std::size_t(field.width()) * field.height();
  const std::size_t step = std::max<std::size_t>(1, pixels / 4096);
  const int lights = field.num_lights();
  std::vector<double> abs_sum, error;
  for (std::size_t i = 0; i < pixels; i += step) {
    const float* v = field.values().data() + i * lights * 3;
    for (int c = 0; c < 3; ++c) {
      double exact = 0, rounded = 0, magnitude = 0;
      for (int l = 0; l < lights; ++l) {
        const float value = v[l * 3 + c];
        exact += value;
        magnitude += std::abs(value);
        rounded += double(float(Eigen::half(value * scale))) / scale;
      }
      abs_sum.push_back(magnitude);
      error.push_back(std::abs(rounded - exact));
    }
  }
  const double largest = abs_sum.empty() ? 0 : *std::max_element(abs_sum.begin(), abs_sum.end());
  double worst = 0;
  for (std::size_t i = 0; i < abs_sum.size(); ++i) {
    if (abs_sum[i] >= 1e-3 * largest && abs_sum[i] > 0) {
      worst = std::max(worst, error[i] / abs_sum[i]);
    }
  }
  return worst;
}

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
    to_half(field.values().data() + y * row, row, scale, half.values_.data() + y * row);
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
