#pragma once
// Which LEDs each fitted pixel saw in cast shadow: the visibility a model render needs so that a
// light behind an occluder does not light the pixel (relight/fit/model_render.h). Known at the
// dome's resolution: a light direction between the LEDs takes the visibility of its nearest LED.
//
// An LED is partly in shadow at a pixel when the pixel's fitted model, lit by that LED alone,
// predicts clearly more than the field measured (by more than kShadowSigmas of the noise): its
// shadow is the missing share, 1 - measured / predicted, in kShadowLevels steps. A penumbra is
// a share between 0 and 1. Lights under the pixel's tangent plane need none (every model is 0
// there); saturated samples are lit.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "capture/field.h"
#include "lightstage/image.h"

namespace ls::relight {

struct FitShadows {
  static constexpr int kBitsPerWord = 24;  // A float32 holds an integer below 2^24 exactly.
  static constexpr int kBitsPerLed = 3;
  static constexpr int kLedsPerWord = kBitsPerWord / kBitsPerLed;
  static constexpr int kShadowLevels = (1 << kBitsPerLed) - 1;  // Level q: shadow share q / 7.
  static constexpr double kShadowSigmas = 4;
  // Unit, stage frame, one per light of the fitted field (its nominal direction).
  std::vector<Eigen::Vector3f> led_dirs_in_stage;
  // words_for(LEDs) channels "shadow.0", "shadow.1", ...: channel w holds LED kLedsPerWord * w +
  // j's level in bits kBitsPerLed * j and up of an integer. Empty: visibility unknown (every LED
  // lit).
  Image words;

  static int words_for(int leds) { return (leds + kLedsPerWord - 1) / kLedsPerWord; }
  // The level (0..kShadowLevels) of LED `led` in a pixel's words.
  static int level(const uint32_t* words, int led) {
    return int((words[led / kLedsPerWord] >> (kBitsPerLed * (led % kLedsPerWord))) & 7u);
  }
  bool empty() const { return words.pixels.empty(); }
  // Every LED lit at every pixel of a width x height frame.
  static FitShadows all_lit(std::vector<Eigen::Vector3f> led_dirs, int width, int height);
  // Pixel (x, y)'s words as integers (words_for(LEDs) of them).
  void pixel_words(int x, int y, uint32_t* out) const;
  // The share of LED `led`'s light that pixel (x, y) does not receive, 0..1.
  double shadow(int x, int y, int led) const;
  void set_pixel_words(int x, int y, const uint32_t* in);
};

// The LED whose visibility each of `dirs` takes: the nearest (index into `leds`, unit directions).
std::vector<int> nearest_leds(const std::vector<Eigen::Vector3f>& leds,
                              const std::vector<Eigen::Vector3f>& dirs);

// The nominal directions of a field's lights (unit, stage frame), as FitShadows keeps them.
std::vector<Eigen::Vector3f> led_dirs_of(const capture::ReflectanceField& field);

}  // namespace ls::relight
