#include "capture/played_photo.h"

#include <algorithm>

#include "lightstage/errors.h"

namespace ls::capture {

namespace {

constexpr int kShots = 2;       // Of each exposure: their difference measures the noise.
constexpr int kDarkFrames = 2;  // Per exposure.

// Every LED off however the photograph ends.
class LightsOff {
 public:
  explicit LightsOff(LightController& lights) : lights_(lights) {}
  ~LightsOff() { lights_.all_off(); }
  LightsOff(const LightsOff&) = delete;
  LightsOff& operator=(const LightsOff&) = delete;

 private:
  LightController& lights_;
};

}  // namespace

PlayedPhoto shoot_played_photo(const Stage& stage, LightController& lights, Camera& camera,
                               const ResponseCurve& response, const std::vector<double>& level,
                               double longest_exposure_s, uint64_t sequence_key_base) {
  if (!(longest_exposure_s > 0)) {
    throw InputError("play: expected a positive exposure, got " +
                     std::to_string(longest_exposure_s) + " s");
  }
  PlayedPhoto photo;
  photo.exposures_s = {longest_exposure_s / 16, longest_exposure_s / 4, longest_exposure_s};
  const size_t steps = photo.exposures_s.size();
  auto request = [&](size_t e, int index) {
    FrameRequest r;
    r.exposure_s = photo.exposures_s[e];
    r.sequence_key = sequence_key_base + e * 16 + uint64_t(index);
    return r;
  };
  std::vector<std::vector<CapturedFrame>> lit(steps), dark(steps);
  {
    LightsOff off(lights);
    lights.set_levels(level);
    for (size_t e = 0; e < steps; ++e) {
      for (int s = 0; s < kShots; ++s) lit[e].push_back(camera.capture(request(e, s)));
    }
    lights.verify_levels();  // The pattern held through every lit frame.
    lights.all_off();
    for (size_t e = 0; e < steps; ++e) {
      for (int r = 0; r < kDarkFrames; ++r) dark[e].push_back(camera.capture(request(e, 8 + r)));
    }
  }
  photo.frames = int(steps) * (kShots + kDarkFrames);
  std::vector<Image> dark_linear;
  for (size_t e = 0; e < steps; ++e) {
    std::vector<const RawFrame*> frames;
    for (const CapturedFrame& f : dark[e]) frames.push_back(&f.raw);
    dark_linear.push_back(mean_dark(frames, response));
  }
  std::vector<Image> merged;  // Per shot: full scale per second, and the usable count.
  for (int s = 0; s < kShots; ++s) {
    std::vector<BracketFrame> bracket;
    for (size_t e = 0; e < steps; ++e) {
      const CapturedFrame& f = lit[e][size_t(s)];
      bracket.push_back({&f.raw, &dark_linear[e], f.exposure_s, f.gain});
    }
    merged.push_back(merge_bracket(bracket, response));
  }
  const int w = merged[0].width, h = merged[0].height, in = merged[0].channels;
  const int camera_channels = in - 1;
  photo.radiance = Image(w, h, 3);
  photo.variance = Image(w, h, 3);
  photo.usable = Image(w, h, 1);
  for (size_t p = 0; p < size_t(w) * h; ++p) {
    const float* a = &merged[0].pixels[p * size_t(in)];
    const float* b = &merged[1].pixels[p * size_t(in)];
    photo.usable.pixels[p] = a[in - 1] > 0 && b[in - 1] > 0 ? 1.0f : 0.0f;
    for (int c = 0; c < 3; ++c) {
      const int k = camera_channels == 1 ? 0 : c;
      // Full scale per second -> radiance (CameraSpec::radiometric_scale).
      const double va = a[k] * stage.camera.radiometric_scale;
      const double vb = b[k] * stage.camera.radiometric_scale;
      photo.radiance.pixels[p * 3 + size_t(c)] = float(0.5 * (va + vb));
      // var(mean of two) = var(one) / 2 = E[(a - b)^2] / 4, taken per pixel (noisy alone; the
      // check sums it over blocks).
      photo.variance.pixels[p * 3 + size_t(c)] = float(0.25 * (va - vb) * (va - vb));
    }
  }
  return photo;
}

}  // namespace ls::capture
