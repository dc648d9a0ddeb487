#pragma once
// PNG's sample arithmetic as OpenImageIO 2.4 did it (image_file_png.cc reads and writes PNG as OIIO
// did): its premultiplication by alpha and its conversions between integer codes and floats, with
// its rounding. Pure arithmetic, apart from libpng.

#include <algorithm>
#include <cmath>
#include <limits>

namespace ls::image_file::png_samples {

// OIIO's premultiplication of a decoded row: integer codes, truncated; with a gAMA chunk (its
// "oiio:Gamma" g), code * (alpha / max)^g in float, truncated.
template <class T>
void associate(T* px, int width, int channels, float gamma) {
  constexpr unsigned kMax = std::numeric_limits<T>::max();
  const int a = channels - 1;
  const float inv_max = float(1.0 / kMax);
  for (int x = 0; x < width; ++x, px += channels) {
    const float k = gamma == 1.0f ? 0.0f : std::pow(float(px[a]) * inv_max, gamma);
    for (int c = 0; c < a; ++c) {
      px[c] = gamma == 1.0f ? T(unsigned(px[c]) * px[a] / kMax) : T(float(px[c]) * k);
    }
  }
}

// OIIO's division by alpha when writing (alpha 0 leaves the colour as it is).
template <class T>
void deassociate(T* px, int width, int channels, float gamma) {
  constexpr unsigned kMax = std::numeric_limits<T>::max();
  const int a = channels - 1;
  for (int x = 0; x < width; ++x, px += channels) {
    if (px[a] == 0) continue;
    const float k = gamma == 1.0f ? 0.0f : std::pow(float(kMax) / float(px[a]), gamma);
    for (int c = 0; c < a; ++c) {  // (Clamped in float: OIIO's cast overflows past 2^32.)
      px[c] = gamma == 1.0f ? T(std::min(kMax, unsigned(px[c]) * kMax / px[a]))
                            : T(std::min(float(kMax), float(px[c]) * k));
    }
  }
}

// Codes to float as OIIO converts them: code * (1 / max) in float.
template <class T>
float to_float(T v) {
  return float(v) * (1.0f / float(std::numeric_limits<T>::max()));
}

// Float to codes as OIIO's vectorised conversion does: round half away from zero, clamped, NaN
// to 0. (OIIO's scalar tail, used for the last values of each thread's share of a row, adds 0.5
// instead, which differs only where x * max lies within a rounding of k + 0.5.)
template <class T>
T from_float(float x) {
  constexpr float kMax = float(std::numeric_limits<T>::max());
  if (std::isnan(x)) return 0;
  return T(std::clamp(std::round(x * kMax), 0.0f, kMax));
}

}  // namespace ls::image_file::png_samples
