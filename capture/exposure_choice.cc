#include "capture/exposure_choice.h"

#include <tbb/parallel_for.h>

#include <algorithm>

#include "capture/led_frames.h"
#include "capture/response.h"
#include "lightstage/errors.h"

namespace ls::capture {

namespace {

constexpr size_t kMaxSamples = 262144;  // Pixels sampled per LED.

}  // namespace

ExposureChoice choose_led_exposures(const Session& previous, int time_step, double coverage,
                                    const MergeOptions& merge) {
  const Stage& stage = previous.stage();
  const CameraSpec& camera = stage.camera;
  const ResponseCurve response = ResponseCurve::given_or_linear(camera);
  const int steps = int(camera.bracket.size());
  auto load = [&](const FrameKey& key) {
    if (!previous.frames().count(key)) {
      throw InputError(previous.dir().string() + ": frame " + key.name(stage) +
                       " is missing: choosing exposures needs every LED's whole bracket");
    }
    return previous.load_frame(key);
  };
  std::vector<Image> darks;  // Linear, per step.
  darks.reserve(size_t(steps));
  for (int e = 0; e < steps; ++e)
    darks.push_back(session_mean_dark(previous, time_step, e, response));
  // Steps from the shortest exposure (times gain) to the longest.
  std::vector<int> by_length(static_cast<size_t>(steps));
  for (int e = 0; e < steps; ++e) by_length[size_t(e)] = e;
  std::sort(by_length.begin(), by_length.end(), [&](int a, int b) {
    return camera.bracket[size_t(a)].exposure_s * camera.bracket[size_t(a)].gain <
           camera.bracket[size_t(b)].exposure_s * camera.bracket[size_t(b)].gain;
  });

  ExposureChoice choice;
  const std::vector<int> order = stage.capture_order();
  std::vector<std::vector<int>> chosen(order.size());
  tbb::parallel_for(size_t(0), order.size(), [&](size_t i) {
    const int led = order[i];
    std::vector<RawFrame> frames;
    frames.reserve(size_t(steps));
    for (int e = 0; e < steps; ++e) frames.push_back(load({time_step, led, e, 0}));
    const size_t values = frames[0].pixels.size();
    const size_t stride = std::max<size_t>(1, values / kMaxSamples);
    std::vector<long> best_count(size_t(steps), 0);
    long lit = 0;
    for (size_t v = 0; v < values; v += stride) {
      const int c = int(v % size_t(camera.channels));
      int best = by_length.front();  // Clipped in every step: the shortest.
      for (const int e : by_length) {
        if (response.to_linear(frames[size_t(e)].pixels[v], c) < merge.saturation_level) best = e;
      }
      const double black = darks[size_t(best)].pixels.empty() ? 0.0 : darks[size_t(best)].pixels[v];
      const double signal = response.to_linear(frames[size_t(best)].pixels[v], c) - black;
      if (signal < merge.floor_level) continue;  // Dark at its best step: no step matters.
      ++lit;
      ++best_count[size_t(best)];
    }
    // The shortest step any pixel needs is kept whatever its share: without it those pixels clip
    // in every step left (a highlight's lower bound), where dropping a longer step only costs the
    // few pixels that needed it some signal (a shorter step still measures them).
    bool shortest_needed_kept = false;
    for (const int e : by_length) {
      const bool needed = best_count[size_t(e)] > 0;
      if ((needed && !shortest_needed_kept) ||
          best_count[size_t(e)] > (1 - coverage) * double(lit)) {
        chosen[i].push_back(e);
        shortest_needed_kept = shortest_needed_kept || needed;
      }
    }
    std::sort(chosen[i].begin(), chosen[i].end());
    if (chosen[i].empty()) chosen[i].push_back(by_length.back());  // Unlit: one long frame.
  });
  for (size_t i = 0; i < order.size(); ++i) {
    const int id = stage.leds[size_t(order[i])].id;
    choice.led_exposures[id] = chosen[i];
    choice.frames_before += steps;
    choice.frames_after += int(chosen[i].size());
    for (int e = 0; e < steps; ++e)
      choice.exposure_s_before += camera.bracket[size_t(e)].exposure_s;
    for (const int e : chosen[i]) choice.exposure_s_after += camera.bracket[size_t(e)].exposure_s;
  }
  return choice;
}

}  // namespace ls::capture
