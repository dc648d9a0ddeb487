#pragma once
// Half-float (IEEE binary16) values of a reflectance field: in a field file (half the bytes on
// disk and through every pass that reads it) and in memory (the viewer's CPU relighting,
// relight/lighting/half_relight.h). Values are stored times a power of two that brings the
// field's largest |value| to 2^14, well inside half's range (65504) and undone exactly on reading;
// half keeps 11 significant bits (relative rounding error <= 2^-11 = 4.9e-4 above 2^-14 after
// the scale). Whether a field may be held in half is its relit error (half_relit_error) against
// kHalfRelitTolerance, the viewer's check.
#include <cstddef>
#include <cstdint>
#include <string>

namespace ls::capture {

class ReflectanceField;  // capture/field.h, which includes this.

// Half storage is refused where, on a sample of the field's pixels, either
// - the field relit from halves is off by more than kHalfRelitTolerance of a pixel's sum |v| (the
//   viewer's check: below what an 8-bit display shows, 1/255 = 3.9e-3 of white), or
// - a value's rounding is more than kHalfNoiseTolerance of the field's measured noise sigma at that
//   value (sqrt(read + shot * v)): a rounding uniform within +-0.25 sigma adds at most 2% to the
//   noise variance the fits weigh residuals by.
// With the power-of-two scale, half keeps 2^-11 relative precision over 28 binary orders below
// the largest value, so the relit check fails only beyond that range; the noise check fails on a
// field measured with less noise than half's rounding (a very deep HDR merge).
inline constexpr double kHalfRelitTolerance = 1e-3;
inline constexpr double kHalfNoiseTolerance = 0.25;

struct HalfCheck {
  double relit_error = 0;   // Worst relative error of a relit pixel and colour.
  double noise_ratio = -1;  // Worst |rounding| / sigma; -1 when the field's noise is not measured.
  bool passes() const {
    return relit_error <= kHalfRelitTolerance && noise_ratio <= kHalfNoiseTolerance;
  }
  void add(const HalfCheck& band);  // The worst of both.
  std::string describe() const;     // "relit error 2.1e-04, rounding 0.03 sigma of the noise"
};

// How a field file holds its values: attribute "lightstage:storage", {"values": "half",
// "scale": S} (stored = value * S), absent for float (a file without it holds floats).
inline constexpr const char* kStorageAttribute = "lightstage:storage";
struct FieldStorage {
  bool half = false;
  float scale = 1;  // A power of two; 1 for float.
  std::string to_json() const;
  // From the attribute's text; InputError naming `file` and the field when it is not one.
  static FieldStorage parse(const std::string& file, const std::string& json);
};

// What a writer is asked for: half where half_relit_error allows it (auto), or always one type.
enum class StorageChoice { kFloat, kHalf, kAuto };
// "float", "half", "auto"; InputError naming the option otherwise.
StorageChoice parse_storage_choice(const std::string& option, const std::string& text);

// The power of two that brings `largest` (a field's largest |value|) to 2^14; 1 for 0.
float half_scale_for(float largest);
float half_scale(const ReflectanceField& field);
float largest_magnitude(const float* values, std::size_t count);

// Worst relative error of half storage (values x scale) on a sample of ~4096 pixels of `field`
// (or of a band) relit under equal weights: per channel |sum half(s v) / s - sum v| / sum |v|,
// over (pixel, channel) pairs whose sum |v| is at least 1e-3 of the largest (darker ones are below
// display precision).
double half_relit_error(const ReflectanceField& field, float scale);
// Both checks on the same sample (the noise ratio where field.noise is measured).
HalfCheck check_half(const ReflectanceField& field, float scale);

// count values times scale into halves, and back (times 1 / scale; returns whether every value
// is finite, checked in the same pass); F16C where the CPU has it. `halves` need not be aligned
// (a mapped file's rows).
void floats_to_halves(const float* values, std::size_t count, float scale, std::uint16_t* halves);
bool halves_to_floats(const void* halves, std::size_t count, float inv_scale, float* values);
// Whether this CPU converts halves in hardware (F16C, with AVX2).
bool cpu_converts_halves();

}  // namespace ls::capture
