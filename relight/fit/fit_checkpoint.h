#pragma once
// The finished bands of a fit in bands of rows (fit_bands.h), kept beside the maps
// (OUT.partial/) until the maps are written, so that a fit that is killed resumes from the bands it
// finished. run.json holds the run's identity (field file, its size and time, options) and band
// height; one file per band holds its normals and per-pixel maps as raw floats (exact) after a
// line of JSON (its size, channels and summary counts), written atomically: a band is there whole
// or not at all.
#include <filesystem>
#include <string>
#include <vector>

#include "lightstage/bands.h"
#include "lightstage/checkpoint_dir.h"
#include "relight/fit/fit.h"
#include "relight/fit/normals.h"

namespace ls::relight {

// A band's checkpoint after its per-pixel fits, or after basis materials were assigned to it
// (its maps.materials then hold only its pixels' count per material).
enum class FitStage { kPerPixel, kMaterials };

class BandCheckpoints {
 public:
  // identity: what must match for bands to be taken from an earlier run (input_identity).
  BandCheckpoints(const std::filesystem::path& out, std::string identity);
  // The band height to fit with, on every rank (agreed_band_rows): an earlier run's with the same
  // identity, so that its bands are reused; otherwise `proposed`, recorded for a later run (an
  // earlier run's bands are dropped).
  int agreed_rows(int proposed, const RankSplit& split) const {
    return agreed_band_rows(dir_, proposed, split);
  }
  // The band of rows [y0, ...) when an earlier run finished it, or false (none, or unreadable:
  // the band is fitted again); led_dirs: the field's (relight::led_dirs_of), for its shadows.
  bool load(int y0, const std::vector<Eigen::Vector3f>& led_dirs, relight::NormalMap& normals,
            relight::ModelMaps& maps, FitStage stage = FitStage::kPerPixel) const;
  void save(int y0, const relight::NormalMap& normals, const relight::ModelMaps& maps,
            FitStage stage = FitStage::kPerPixel) const;
  // Once the maps are written.
  void remove() const { dir_.remove(); }
  std::filesystem::path file(int y0, FitStage stage) const;

 private:
  CheckpointDir dir_;
};

}  // namespace ls::relight
