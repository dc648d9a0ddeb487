#pragma once
// Bright sources of an environment map: a sun, a lamp, a small window, light concentrated
// within a few degrees, far narrower than the spacing of a dome's LEDs. Relit by LED cells, such a
// source is spread over the cells around it, so each shadow comes out as two or three offset
// copies at the LEDs' directions (the classic artefact of Debevec et al. 2000). Split off, a source
// is rendered at its true direction (relight/sources/source_render.h) while the smooth rest of the
// map is relit by the cells as before.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "physics/envmap.h"

namespace ls::relight {

struct BrightSource {
  Eigen::Vector3d dir{0, 1, 0};  // Unit, toward the source's energy centroid, in the map's frame.
  double radius_rad = 0.0;       // Of the uniform disc with the same angular spread.
  // Integral over the source of (L - the background around it) dw: the irradiance it gives at
  // normal incidence, per channel. The background stays in the rest of the map.
  Eigen::Vector3d irradiance_rgb{0, 0, 0};
  double energy_share = 0.0;  // Of the whole map's luminance integral, in [0, 1].

  std::string describe() const;  // Direction, size and share, one line.
};

struct BrightSourceOptions {
  // A pixel belongs to a source when its luminance is at least min_contrast x the map's mean
  // luminance (the sun of a clear sky is ~10^4 x; the lamps of a studio a few x, and stay in the
  // map). A region too wide at that level is searched for a compact core at doubling levels.
  double min_contrast = 20.0;
  double max_radius_deg = 5.0;     // Wider regions are left to the LED cells.
  double min_energy_share = 0.01;  // Dimmer ones too: their ghosts would not show.
  int max_sources = 4;
  std::string validate() const;  // Empty when valid, else the option and its range.
};

struct SplitEnvironment {
  physics::EnvironmentMap
      rest;  // The map without its sources: rest + sources == the map, per channel.
  std::vector<BrightSource> sources;  // Brightest first.
};

// Finds up to max_sources bright sources (brightest first) and removes them from the map: each
// source's pixels keep min(L, background) in the rest, where the background is the mean radiance
// of the pixels bordering it.
SplitEnvironment split_bright_sources(const physics::EnvironmentMap& map,
                                      const BrightSourceOptions& options = {});

}  // namespace ls::relight
