#include "capture/led_frames.h"

#include <map>
#include <utility>

#include "capture/hdr_merge.h"
#include "lightstage/errors.h"

namespace ls::capture {
namespace {

// LEDs whose brackets feed the response recovery (kRecover): a few views of the scene give the
// solver a wider spread of radiances than one.
constexpr int kRecoveryLeds = 3;

}  // namespace

std::vector<LedFrames> index_led_frames(const Session& session, int time_step,
                                        const std::vector<int>& order,
                                        std::vector<std::vector<FrameKey>>* dark_keys) {
  const Stage& stage = session.stage();
  const size_t steps = stage.camera.bracket.size();
  std::map<int, size_t> position_of_led;
  std::vector<LedFrames> brackets(order.size());
  for (size_t i = 0; i < order.size(); ++i) {
    brackets[i].led_index = order[i];
    brackets[i].records.assign(steps, nullptr);
    brackets[i].planned.assign(steps, false);
    for (const int e : stage.exposures_of(order[i])) brackets[i].planned[size_t(e)] = true;
    position_of_led[order[i]] = i;
  }
  dark_keys->assign(steps, {});
  for (const auto& [key, record] : session.frames()) {
    if (key.time_step != time_step) continue;
    if (key.exposure_index < 0 || size_t(key.exposure_index) >= steps) continue;
    const size_t e = size_t(key.exposure_index);
    if (key.is_dark()) {
      (*dark_keys)[e].push_back(key);
    } else if (key.repeat == 0) {  // Not the reference LED's drift shots.
      auto it = position_of_led.find(key.led_index);
      if (it != position_of_led.end() && brackets[it->second].planned[e]) {
        brackets[it->second].records[e] = &record;
      }
    }
  }
  return brackets;
}

Image session_mean_dark(const Session& session, int time_step, int exposure_index,
                        const ResponseCurve& response) {
  std::vector<RawFrame> frames;
  for (int r = 0; r < session.stage().plan.dark_frames; ++r) {
    const FrameKey key{time_step, -1, exposure_index, r};
    if (session.frames().count(key)) frames.push_back(session.load_frame(key));
  }
  std::vector<const RawFrame*> pointers;
  pointers.reserve(frames.size());
  for (const RawFrame& f : frames) pointers.push_back(&f);
  return pointers.empty() ? Image() : mean_dark(pointers, response);
}

ResponseCurve recover_from_session(const Session& session, const std::vector<LedFrames>& brackets,
                                   const std::vector<bool>& usable) {
  const Stage& stage = session.stage();
  // "Brightest" without reading every frame: the LEDs nearest the camera axis (front light reaches
  // what the camera sees) with the highest calibrated irradiance.
  std::vector<std::pair<double, size_t>> scored;
  for (size_t i = 0; i < brackets.size(); ++i) {
    if (!usable[i] || !brackets[i].full()) continue;
    const Led& led = stage.leds[brackets[i].led_index];
    const double facing = std::max(0.05, led.dir_in_stage.z());
    scored.push_back({-led.irradiance_rgb().mean() * facing, i});
  }
  if (scored.empty()) {
    throw InputError(session.dir().string() +
                     ": camera response 'recover' needs at least one LED with a complete bracket");
  }
  std::sort(scored.begin(), scored.end());
  scored.resize(std::min<size_t>(scored.size(), kRecoveryLeds));

  // The solver wants one static scene per exposure: put the chosen LEDs' frames side by side, so
  // each exposure step becomes one wide image of several lighting conditions.
  const size_t num_exposures = brackets[scored[0].second].records.size();
  std::vector<RawFrame> tiled(num_exposures);
  std::vector<double> exposure_gain(num_exposures);
  for (size_t e = 0; e < num_exposures; ++e) {
    std::vector<RawFrame> parts;
    parts.reserve(scored.size());
    for (const auto& [score, i] : scored) {
      parts.push_back(session.load_frame(brackets[i].records[e]->key));
    }
    const RawFrame& first = parts[0];
    for (const RawFrame& p : parts) {
      if (p.width != first.width || p.height != first.height || p.channels != first.channels ||
          p.bit_depth != first.bit_depth) {
        throw InputError(session.dir().string() + ": frames differ in size or format");
      }
    }
    RawFrame& t = tiled[e];
    t.width = first.width * int(parts.size());
    t.height = first.height;
    t.channels = first.channels;
    t.bit_depth = first.bit_depth;
    t.pixels.resize(size_t(t.width) * t.height * t.channels);
    const size_t part_row = size_t(first.width) * first.channels;
    for (int y = 0; y < t.height; ++y) {
      for (size_t p = 0; p < parts.size(); ++p) {
        std::copy_n(parts[p].pixels.data() + y * part_row, part_row,
                    t.pixels.data() + y * part_row * parts.size() + p * part_row);
      }
    }
    const FrameRecord* record = brackets[scored[0].second].records[e];
    exposure_gain[e] = record->exposure_s * record->gain;
  }
  std::vector<const RawFrame*> frames;
  frames.reserve(tiled.size());
  for (const RawFrame& t : tiled) frames.push_back(&t);
  return recover_response(frames, exposure_gain);
}

}  // namespace ls::capture
