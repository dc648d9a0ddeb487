#include "capture/hdr_merge.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "lightstage/errors.h"

namespace ls::capture {
namespace {

// Most channels a merge handles (RGB + one spare); keeps per-pixel scratch on the stack.
constexpr int kMaxChannels = 4;
// Width of the ramp below the saturation level, as a fraction of it: the weight falls from 1 at
// (1 - kSaturationRamp) * saturation_level to 0 at saturation_level. A soft edge keeps a sample
// whose noise straddles the threshold from switching the result abruptly.
constexpr double kSaturationRamp = 0.2;
// Weight left at (and below) the noise floor, so that a pixel dark in every exposure still gets the
// exposure-weighted mean instead of 0/0.
constexpr float kFloorWeight = 1e-3f;

void check_frame(const RawFrame& f, const RawFrame& first, const ResponseCurve& response,
                 size_t index) {
  if (f.width != first.width || f.height != first.height || f.channels != first.channels) {
    throw InputError("HDR merge: frame " + std::to_string(index) + " is " +
                     std::to_string(f.width) + "x" + std::to_string(f.height) + "x" +
                     std::to_string(f.channels) + ", frame 0 is " + std::to_string(first.width) +
                     "x" + std::to_string(first.height) + "x" + std::to_string(first.channels));
  }
  if (f.pixels.size() != size_t(f.width) * f.height * f.channels) {
    throw InputError("HDR merge: frame " + std::to_string(index) + " holds " +
                     std::to_string(f.pixels.size()) + " values, expected width*height*channels");
  }
  if (f.bit_depth != response.bit_depth()) {
    throw InputError("HDR merge: frame " + std::to_string(index) + " is " +
                     std::to_string(f.bit_depth) + "-bit but the response curve is " +
                     std::to_string(response.bit_depth()) + "-bit");
  }
  if (response.channels() != 1 && response.channels() != f.channels) {
    throw InputError("HDR merge: frames have " + std::to_string(f.channels) +
                     " channels but the response curve has " + std::to_string(response.channels()));
  }
}

}  // namespace

Image merge_bracket(const std::vector<BracketFrame>& bracket, const ResponseCurve& response,
                    const MergeOptions& options) {
  if (bracket.empty()) throw InputError("HDR merge: the bracket has no frames");
  if (!(options.saturation_level > 0 && options.saturation_level <= 1) ||
      !(options.floor_level >= 0 && options.floor_level < options.saturation_level)) {
    throw InputError("HDR merge: need 0 <= floor_level < saturation_level <= 1, got floor " +
                     std::to_string(options.floor_level) + ", saturation " +
                     std::to_string(options.saturation_level));
  }
  for (size_t k = 0; k < bracket.size(); ++k) {
    if (bracket[k].raw == nullptr) {
      throw InputError("HDR merge: frame " + std::to_string(k) + " is missing");
    }
  }
  const RawFrame& first = *bracket[0].raw;
  const int width = first.width;
  const int height = first.height;
  const int channels = first.channels;
  if (channels < 1 || channels > kMaxChannels) {
    throw InputError("HDR merge: frames must have 1 to " + std::to_string(kMaxChannels) +
                     " channels, got " + std::to_string(channels));
  }
  const int num_exposures = int(bracket.size());
  std::vector<float> exposure_gain(num_exposures);
  int shortest = 0;
  for (int k = 0; k < num_exposures; ++k) {
    const BracketFrame& b = bracket[k];
    check_frame(*b.raw, first, response, size_t(k));
    if (b.dark_linear != nullptr) {
      const Image& d = *b.dark_linear;
      if (d.width != width || d.height != height || d.channels != channels ||
          d.pixels.size() != size_t(width) * height * channels) {
        throw InputError("HDR merge: the dark frame of exposure " + std::to_string(k) +
                         " does not match the frames' size and channels");
      }
    }
    const double tg = b.exposure_s * b.gain;
    if (!(tg > 0) || !std::isfinite(tg)) {
      throw InputError("HDR merge: exposure " + std::to_string(k) +
                       " needs positive exposure_s and gain, got " + std::to_string(b.exposure_s) +
                       " s at gain " + std::to_string(b.gain));
    }
    exposure_gain[k] = float(tg);
    if (tg < exposure_gain[shortest]) shortest = k;
  }

  const int max_dn = (1 << response.bit_depth()) - 1;
  const float saturation = float(options.saturation_level);
  const float ramp_start = float(options.saturation_level * (1.0 - kSaturationRamp));
  const float inv_ramp = 1.0f / (saturation - ramp_start);
  const float floor_level = float(options.floor_level);
  const float inv_floor = floor_level > 0 ? 1.0f / floor_level : 0.0f;
  const std::vector<float>& lut = response.lut();
  const size_t lut_stride = response.channels() == 1 ? 0 : size_t(max_dn) + 1;

  Image out(width, height, channels + 1);
  if (channels == 3) out.channel_names = {"R", "G", "B", "samples"};

  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        const size_t in_index = (size_t(y) * width + x) * channels;
        float* o = &out.pixels[(size_t(y) * width + x) * (channels + 1)];
        int min_count = num_exposures;
        for (int c = 0; c < channels; ++c) {
          const float* channel_lut = lut.data() + lut_stride * c;
          double weighted_sum = 0;
          double weight_total = 0;
          int count = 0;
          float shortest_signal = 0;
          for (int k = 0; k < num_exposures; ++k) {
            const BracketFrame& b = bracket[k];
            const int dn = std::min<int>(b.raw->pixels[in_index + c], max_dn);
            const float linear = channel_lut[dn];
            const float dark = b.dark_linear ? b.dark_linear->pixels[in_index + c] : 0.0f;
            // Negative values after dark subtraction are kept: noise is symmetric about the true
            // signal, and clipping at 0 would bias dark pixels upward.
            const float above_dark = linear - dark;
            const float signal = above_dark / exposure_gain[k];
            if (k == shortest) shortest_signal = signal;
            // Saturation is a property of the raw sensor value, so test before dark subtraction.
            if (dn >= max_dn || linear >= saturation) continue;
            const float w_high = std::min(1.0f, (saturation - linear) * inv_ramp);
            const float w_low =
                inv_floor > 0 ? std::clamp(above_dark * inv_floor, kFloorWeight, 1.0f) : 1.0f;
            // Longer exposures (and higher gain) collected more photons: weighting by exposure *
            // gain is inverse-variance weighting in the shot-noise limit.
            const float w = std::min(w_high, w_low) * exposure_gain[k];
            weighted_sum += double(w) * signal;
            weight_total += w;
            ++count;
          }
          // Every exposure saturated: the shortest one's value is a lower bound, flagged by count
          // 0.
          o[c] = count > 0 ? float(weighted_sum / weight_total) : shortest_signal;
          min_count = std::min(min_count, count);
        }
        // One count per pixel: the fewest usable samples of any channel, so 0 flags a pixel with
        // any channel clipped in every exposure.
        o[channels] = float(min_count);
      }
    }
  });
  return out;
}

Image mean_dark(const std::vector<const RawFrame*>& darks, const ResponseCurve& response) {
  if (darks.empty()) throw InputError("mean dark: no dark frames given");
  for (size_t k = 0; k < darks.size(); ++k) {
    if (darks[k] == nullptr)
      throw InputError("mean dark: dark frame " + std::to_string(k) + " is missing");
    check_frame(*darks[k], *darks[0], response, k);
  }
  const RawFrame& first = *darks[0];
  const int channels = first.channels;
  const int max_dn = (1 << response.bit_depth()) - 1;
  const std::vector<float>& lut = response.lut();
  const size_t lut_stride = response.channels() == 1 ? 0 : size_t(max_dn) + 1;
  const float inv_count = 1.0f / float(darks.size());
  Image out(first.width, first.height, channels);
  const size_t row_values = size_t(first.width) * channels;
  tbb::parallel_for(tbb::blocked_range<int>(0, first.height),
                    [&](const tbb::blocked_range<int>& rows) {
                      for (int y = rows.begin(); y < rows.end(); ++y) {
                        const size_t begin = size_t(y) * row_values;
                        for (size_t i = begin; i < begin + row_values; ++i) {
                          const size_t c = i % size_t(channels);
                          float sum = 0;
                          for (const RawFrame* d : darks) {
                            sum += lut[lut_stride * c + std::min<int>(d->pixels[i], max_dn)];
                          }
                          out.pixels[i] = sum * inv_count;
                        }
                      }
                    });
  return out;
}

}  // namespace ls::capture
