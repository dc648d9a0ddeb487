// Stage files (lightstage/stage.h): parse_stage on any text. What it accepts must also survive
// what `lightstage stage FILE` and a capture do first with a stage (its LEDs' cells and coverage,
// its capture order and step times) and round-trip through stage_to_json, the form
// `lightstage stage --write` and every session manifest hold.
#include <cmath>
#include <optional>

#include "fuzz/fuzz_support.h"
#include "lightstage/stage.h"
#include "relight/lighting/light_cells.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::optional<ls::Stage> stage;
  try {
    stage = ls::parse_stage(ls::fuzz::as_text(data, size), "fuzz_stage.json");
  } catch (const ls::InputError&) {
    return 0;
  }
  (void)stage->capture_order();
  for (int t = 0; t < std::min(stage->plan.time_steps, 100); ++t) {
    (void)stage->plan.step_time_s(t);
    (void)stage->plan.step_interval_s(t);
  }
  // `lightstage stage` at a coarse resolution (the same code; a fine grid only costs time).
  if (stage->leds.size() <= 1000) {
    (void)ls::relight::LightCells::compute(stage->led_directions(),
                                           stage->coverage_radius_deg * M_PI / 180.0,
                                           /*resolution=*/64, /*supersample=*/1);
  }
  // Not inside expect_only_input_errors: a stage the reader accepted and whose own JSON it then
  // refuses is a finding.
  const ls::Stage again = ls::parse_stage(ls::stage_to_json(*stage), "round_trip.json");
  LS_CHECK(again.leds.size() == stage->leds.size() &&
               again.camera.bracket.size() == stage->camera.bracket.size(),
           "the stage changed through stage_to_json");
  return 0;
}
