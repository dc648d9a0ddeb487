#include "capture/reference_drift.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "capture/led_frames.h"
#include "lightstage/errors.h"

namespace ls::capture {

namespace {

constexpr double kSaturatedFraction = 0.98;  // Of full scale: such values are left out.

RawFrame load(const Session& session, const FrameKey& key) {
  if (!session.frames().count(key)) {
    throw InputError(session.dir().string() + ": frame " + key.name(session.stage()) +
                     " (a drift reference shot) was not captured; resume the capture");
  }
  return session.load_frame(key);
}

}  // namespace

double ReferenceDrift::output_at_led(int position) const {
  const double at = position + 0.5;
  if (positions.empty()) return 1.0;
  if (at <= positions.front()) return output.front();
  for (size_t k = 1; k < positions.size(); ++k) {
    if (at <= positions[k]) {
      const double w = (at - positions[k - 1]) / (positions[k] - positions[k - 1]);
      return (1 - w) * output[k - 1] + w * output[k];
    }
  }
  return output.back();
}

double ReferenceDrift::largest_change() const {
  double largest = 0.0;
  for (const double v : output) largest = std::max(largest, std::abs(v - 1.0));
  return largest;
}

std::string ReferenceDrift::describe(const Stage& stage) const {
  char text[200];
  const auto [low, high] = std::minmax_element(output.begin(), output.end());
  std::snprintf(text, sizeof text,
                "time step %d: the reference LED %d's output ranged %.2f%% to %+.2f%% of its first "
                "shot over %zu shots (last %+.2f%%)",
                time_step, stage.leds[size_t(stage.led_index(stage.plan.reference_led))].id,
                (*low - 1) * 100, (*high - 1) * 100, output.size(), (output.back() - 1) * 100);
  return text;
}

std::optional<ReferenceDrift> measure_reference_drift(const Session& session, int time_step,
                                                      const ResponseCurve& response) {
  const Stage& stage = session.stage();
  const int reference = stage.led_index(stage.plan.reference_led);
  const int leds = int(stage.capture_order().size());
  const int shots = stage.plan.reference_shots(leds);
  if (reference < 0 || shots < 2) return std::nullopt;
  ReferenceDrift drift;
  drift.time_step = time_step;
  for (int k = 0; k < shots; ++k) {
    drift.positions.push_back(std::min(k * stage.plan.reference_every, leds));
  }
  std::vector<double> best;  // Each shot's signal on the bracket step with the most of it.
  for (int e = 0; e < int(stage.camera.bracket.size()); ++e) {
    const Image dark = session_mean_dark(session, time_step, e, response);
    std::vector<RawFrame> frames;
    frames.reserve(size_t(shots));
    for (int k = 0; k < shots; ++k) {
      frames.push_back(load(session, {time_step, reference, e, k + 1}));
    }
    const RawFrame& first = frames[0];
    const double saturated = kSaturatedFraction * first.max_value();
    std::vector<double> signal(size_t(shots), 0.0);
    for (size_t i = 0; i < first.pixels.size(); ++i) {
      if (std::any_of(frames.begin(), frames.end(), [&](const RawFrame& f) {
            return f.pixels.size() != first.pixels.size() || f.pixels[i] >= saturated;
          })) {
        continue;
      }
      const int c = int(i % size_t(first.channels));
      const double black = dark.pixels.empty() ? 0.0 : dark.pixels[i];
      for (int k = 0; k < shots; ++k) {
        signal[size_t(k)] += response.to_linear(frames[size_t(k)].pixels[i], c) - black;
      }
    }
    if (best.empty() || signal[0] > best[0]) {
      best = signal;
      drift.exposure_index = e;
    }
  }
  if (best.empty() || !(best[0] > 0)) return std::nullopt;  // No signal: nothing to measure.
  for (const double s : best) drift.output.push_back(s / best[0]);
  return drift;
}

std::optional<ReferenceDrift> build_drift(const Session& session, int time_step,
                                          const ResponseCurve& response, bool correct,
                                          std::vector<std::string>* warnings) {
  std::optional<ReferenceDrift> drift;
  if (correct && session.stage().plan.reference_led < 0) {
    throw InputError(session.stage().source +
                     ": plan.reference_led: --correct-drift divides out the drift of a reference "
                     "LED shot through the capture, and this plan shoots none");
  }
  try {
    drift = measure_reference_drift(session, time_step, response);
  } catch (const InputError& e) {
    warnings->push_back(std::string("drift not measured: ") + e.what());
    return std::nullopt;
  }
  if (drift && drift->largest_change() > 0.005) {
    warnings->push_back(drift->describe(session.stage()) +
                        (correct ? ": divided out of every LED"
                                 : ": not corrected (build --correct-drift divides it out)"));
  }
  if (!correct) drift.reset();
  return drift;
}

}  // namespace ls::capture
