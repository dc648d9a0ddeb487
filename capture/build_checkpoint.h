#pragma once
// The LEDs a build in bands has merged (lightstage build --memory), kept beside the field
// (OUT.partial/, lightstage/checkpoint_dir.h) until it is written, so that a build that is killed
// resumes from them: their images in the spill (leds.spill, capture/band_spill.h) and, per LED, a
// record (led_I) of what its merge counted beside its image: its saturated samples and its
// photon-transfer samples, written after the image is in the spill. A resumed build gives the
// bytes of an uninterrupted one.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "capture/build_field.h"
#include "capture/noise_estimate.h"
#include "lightstage/checkpoint_dir.h"
#include "lightstage/session.h"

namespace ls::capture {

class BuildCheckpoint {
 public:
  BuildCheckpoint(const std::filesystem::path& out, const Session& session,
                  const BuildOptions& options);
  // Its folder: the band height the run agrees on (agreed_band_rows: an earlier run's, its spill
  // laid out by it) and the rest.
  const CheckpointDir& dir() const { return dir_; }
  std::filesystem::path spill_path() const { return dir_.dir() / "leds.spill"; }

  struct Led {
    long long saturated = 0;  // Samples saturated in every exposure.
    std::vector<TransferSample> transfer;
  };
  // Field light i's record when an earlier run (or this one) finished its merge; none when absent
  // or unreadable (it is merged again).
  std::optional<Led> load(int light) const;
  void save(int light, const Led& led) const;
  void remove() const { dir_.remove(); }

 private:
  CheckpointDir dir_;
};

}  // namespace ls::capture
