#pragma once
// Compact reflectance fields: representations of R(x, l) that are smaller than the raw
// field (pixels x LEDs x 3 floats), relight faster, and can be lit from directions between the
// LEDs. Each is a point on a size / speed / accuracy chart (lightstage bench compact).
//
// Lighting is a set of distant lights, (relight/lighting/lighting.h):
// unit directions toward the light in the stage frame, each with its irradiance at normal
// incidence per channel. An environment map becomes such a set either one light per LED cell
// (LightingForModels::led_cells, the lights field relighting uses) or one per texel of a coarse
// grid (LightingForModels::environment). Output is linear radiance in field units, like
// relight(field, weights): a point light of unit irradiance along an LED's direction reproduces
// that LED's image.
#include <Eigen/Core>
#include <string>

#include "lightstage/image.h"
#include "relight/lighting/lighting.h"

namespace ls::relight {

class CompactField {
 public:
  virtual ~CompactField() = default;

  virtual std::string name() const = 0;  // E.g. "pca k=8", "ptm-lrgb", "hsh3", "models".
  virtual int width() const = 0;
  virtual int height() const = 0;
  // Storage per pixel in the representation's own format (what `lightstage compress` writes),
  // with per-image tables (bases, scale/bias) amortised over the pixels.
  virtual double bytes_per_pixel() const = 0;

  // 3-channel linear radiance image; `out` is reused when it already has the right size. Never
  // NaN. The linear representations project the lighting onto their light basis once (a pass over
  // the lights), then spend num_terms multiply-adds per pixel and channel.
  virtual void relight_into(const LightingForModels& lights, Image& out) const = 0;

  Image relight(const LightingForModels& lights) const {
    Image out;
    relight_into(lights, out);
    return out;
  }
  // One distant light of irradiance `irradiance_rgb` (at normal incidence) from dir_in_stage.
  Image relight_point(const Eigen::Vector3d& dir_in_stage,
                      const Eigen::Vector3d& irradiance_rgb = Eigen::Vector3d::Ones()) const {
    return relight(LightingForModels::directional(dir_in_stage, irradiance_rgb));
  }
};

}  // namespace ls::relight
