#pragma once
// lightstage play: the dome plays an environment map (each LED at its share of the map's light,
// LightController::set_levels), the camera photographs it, and the photograph is compared with the
// field relit under the same levels: the superposition check (relight/lighting/superposition.h).
// When they disagree beyond their noise, the dome is bisected (halves played and checked in turn)
// down to the LEDs whose light is not what the field recorded.
#include <filesystem>
#include <string>
#include <vector>

#include "app/jobs/job.h"
#include "capture/field.h"
#include "lightstage/hardware.h"
#include "relight/lighting/superposition.h"

namespace ls::jobs {

struct PlayOptions {
  std::filesystem::path env_map;
  double rotate_deg = 0.0;  // About +Y, as relight --rotate.
  // photo.exr and relit.exr (radiance), compare.png (photograph | relit | difference x 8) and
  // report.json; empty: nothing written.
  std::filesystem::path out_dir;
  bool locate = true;  // Bisect the dome when the map's check fails.
  // Also audit the map's LEDs in groups of this many neighbours, each LED fully on (0: only
  // bisect when the whole map fails). An LED with a small share of the map changes its photograph
  // little; fully on in a small group its change stands out. Costs a pattern per group.
  int audit_group_size = 0;
  // The photograph may be this much brighter or dimmer than the relit field (the LED calibration's
  // and the merge's tolerance); see SuperpositionCheck::disagrees.
  double gain_tolerance = 0.01;
};

// An LED whose light, played alone, is not what the field holds.
struct SuspectLed {
  int led_id = 0;
  relight::SuperpositionCheck check;  // Played alone against its field image times its level.
  std::string describe() const;
};

struct PlayResult {
  relight::SuperpositionCheck check;  // The whole map.
  bool agrees = true;
  std::vector<SuspectLed> suspects;
  // Groups that disagreed while none of their halves did (several small errors adding up).
  std::vector<std::vector<int>> unresolved_groups;  // LED ids.
  int patterns = 0;                                 // Played: the map, then the bisection's.
  int frames = 0;
  double uncovered_fraction = 0.0;  // Of the map's light that no LED can play.
};

// play_map on a session's own stage and back-end (as `capture --resume` opens them: the
// simulated stage with the session's scene and seed) against `field` (built from it).
struct PlaySessionOptions {
  std::filesystem::path session_dir;
  std::filesystem::path field;
  PlayOptions play;
};
PlayResult play_session(const PlaySessionOptions& options, const ProgressFn& progress = {});

// Throws InputError for a bad map or a field not of this stage and view, HardwareError when the
// lights cannot be set to levels. Every LED is off when it returns or throws.
PlayResult play_map(const Stage& stage, const capture::ReflectanceField& field,
                    LightController& lights, Camera& camera, const PlayOptions& options,
                    const ProgressFn& progress = {});

}  // namespace ls::jobs
