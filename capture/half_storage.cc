#include "capture/half_storage.h"

#include <cpuid.h>
#include <immintrin.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <vector>

#include "capture/field.h"
#include "lightstage/errors.h"

namespace ls::capture {

bool cpu_converts_halves() {
  static const bool has = [] {
    unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
    if (!__get_cpuid(1, &eax, &ebx, &ecx, &edx)) return false;
    constexpr unsigned kF16cBit = 1u << 29;  // CPUID.1:ECX.F16C
    return (ecx & kF16cBit) != 0 && __builtin_cpu_supports("avx2");
  }();
  return has;
}

namespace {

__attribute__((target("avx2,f16c"))) void to_halves_f16c(const float* in, std::size_t count,
                                                         float scale, std::uint16_t* out) {
  const __m256 s = _mm256_set1_ps(scale);
  std::size_t i = 0;
  for (; i + 8 <= count; i += 8) {
    const __m128i h =
        _mm256_cvtps_ph(_mm256_mul_ps(_mm256_loadu_ps(in + i), s), _MM_FROUND_TO_NEAREST_INT);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i), h);
  }
  for (; i < count; ++i) out[i] = Eigen::half(in[i] * scale).x;
}

// Whether every value converted is finite (checked in the same pass: |v| < infinity, false for
// NaN).
__attribute__((target("avx2,f16c"))) bool to_floats_f16c(const char* in, std::size_t count,
                                                         float inv_scale, float* out) {
  const __m256 s = _mm256_set1_ps(inv_scale);
  const __m256 magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 infinity = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  __m256 finite = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  std::size_t i = 0;
  for (; i + 8 <= count; i += 8) {
    const __m128i h = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + 2 * i));
    const __m256 v = _mm256_mul_ps(_mm256_cvtph_ps(h), s);
    finite =
        _mm256_and_ps(finite, _mm256_cmp_ps(_mm256_and_ps(v, magnitude), infinity, _CMP_LT_OQ));
    _mm256_storeu_ps(out + i, v);
  }
  bool all_finite = _mm256_movemask_ps(finite) == 0xff;
  for (; i < count; ++i) {
    std::uint16_t bits = 0;
    std::memcpy(&bits, in + 2 * i, 2);
    out[i] = float(Eigen::numext::bit_cast<Eigen::half>(bits)) * inv_scale;
    all_finite = all_finite && std::isfinite(out[i]);
  }
  return all_finite;
}

}  // namespace

std::string FieldStorage::to_json() const {
  return nlohmann::json{{"values", half ? "half" : "float"}, {"scale", scale}}.dump();
}

FieldStorage FieldStorage::parse(const std::string& file, const std::string& json) {
  const std::string where = file + ": attribute '" + kStorageAttribute + "': ";
  try {
    const nlohmann::json j = nlohmann::json::parse(json);
    const std::string values = j.at("values").get<std::string>();
    if (values != "half" && values != "float") {
      throw InputError(where + "values: expected \"half\" or \"float\", got \"" + values + "\"");
    }
    const double scale = j.at("scale").get<double>();
    // A power of two that a float holds (stored = value * scale, undone exactly).
    int exponent = 0;
    if (!std::isfinite(scale) || scale <= 0 || std::frexp(scale, &exponent) != 0.5 ||
        exponent < -100 || exponent > 100) {
      throw InputError(where + "scale: expected a power of two, got " + j.at("scale").dump());
    }
    return {values == "half", float(scale)};
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where + e.what());
  }
}

StorageChoice parse_storage_choice(const std::string& option, const std::string& text) {
  if (text == "float") return StorageChoice::kFloat;
  if (text == "half") return StorageChoice::kHalf;
  if (text == "auto") return StorageChoice::kAuto;
  throw InputError(option + ": expected auto, half or float, got '" + text + "'");
}

float half_scale_for(float largest) {
  return largest > 0 && std::isfinite(largest) ? std::ldexp(1.0f, 14 - std::ilogb(largest)) : 1.0f;
}

float largest_magnitude(const float* values, std::size_t count) {
  float largest = 0;
  for (std::size_t i = 0; i < count; ++i) largest = std::max(largest, std::abs(values[i]));
  return largest;
}

float half_scale(const ReflectanceField& field) {
  return half_scale_for(largest_magnitude(field.values().data(), field.values().size()));
}

void HalfCheck::add(const HalfCheck& band) {
  relit_error = std::max(relit_error, band.relit_error);
  noise_ratio = std::max(noise_ratio, band.noise_ratio);
}

std::string HalfCheck::describe() const {
  char text[160];
  if (noise_ratio >= 0) {
    std::snprintf(
        text, sizeof text,
        "relit error %.1e (at most %.0e), rounding %.3f sigma of the noise (at most %.2f)",
        relit_error, kHalfRelitTolerance, noise_ratio, kHalfNoiseTolerance);
  } else {
    std::snprintf(text, sizeof text, "relit error %.1e (at most %.0e; noise not measured)",
                  relit_error, kHalfRelitTolerance);
  }
  return text;
}

double half_relit_error(const ReflectanceField& field, float scale) {
  return check_half(field, scale).relit_error;
}

HalfCheck check_half(const ReflectanceField& field, float scale) {
  const std::size_t pixels = std::size_t(field.width()) * field.height();
  const std::size_t step = std::max<std::size_t>(1, pixels / 4096);
  const int lights = field.num_lights();
  const FieldNoise& noise = field.noise;
  HalfCheck check;
  if (noise.measured) check.noise_ratio = 0;
  std::vector<double> abs_sum, error;
  for (std::size_t i = 0; i < pixels; i += step) {
    const float* v = field.values().data() + i * lights * 3;
    for (int c = 0; c < 3; ++c) {
      double exact = 0, rounded = 0, magnitude = 0;
      for (int l = 0; l < lights; ++l) {
        const float value = v[l * 3 + c];
        const double half_value = double(float(Eigen::half(value * scale))) / scale;
        exact += value;
        magnitude += std::abs(value);
        rounded += half_value;
        if (noise.measured) {
          const double variance =
              noise.read_variance + noise.shot_variance_per_unit * std::max(0.0f, value);
          const double rounding = std::abs(half_value - value);
          if (rounding > 0) {
            check.noise_ratio =
                std::max(check.noise_ratio, variance > 0 ? rounding / std::sqrt(variance) : 1e30);
          }
        }
      }
      abs_sum.push_back(magnitude);
      error.push_back(std::abs(rounded - exact));
    }
  }
  const double largest = abs_sum.empty() ? 0 : *std::max_element(abs_sum.begin(), abs_sum.end());
  for (std::size_t i = 0; i < abs_sum.size(); ++i) {
    if (abs_sum[i] >= 1e-3 * largest && abs_sum[i] > 0) {
      check.relit_error = std::max(check.relit_error, error[i] / abs_sum[i]);
    }
  }
  return check;
}

void floats_to_halves(const float* values, std::size_t count, float scale, std::uint16_t* halves) {
  if (cpu_converts_halves()) return to_halves_f16c(values, count, scale, halves);
  for (std::size_t i = 0; i < count; ++i) halves[i] = Eigen::half(values[i] * scale).x;
}

bool halves_to_floats(const void* halves, std::size_t count, float inv_scale, float* values) {
  const char* bytes = static_cast<const char*>(halves);
  if (cpu_converts_halves()) return to_floats_f16c(bytes, count, inv_scale, values);
  bool all_finite = true;
  for (std::size_t i = 0; i < count; ++i) {
    std::uint16_t bits = 0;
    std::memcpy(&bits, bytes + 2 * i, 2);
    values[i] = float(Eigen::numext::bit_cast<Eigen::half>(bits)) * inv_scale;
    all_finite = all_finite && std::isfinite(values[i]);
  }
  return all_finite;
}

}  // namespace ls::capture
