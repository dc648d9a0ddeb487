#include "viewer/view_lighting.h"

#include <algorithm>
#include <utility>

#include "relight/lighting/light_cells.h"
#include "relight/sources/map_relight.h"

namespace ls::viewer {

namespace {

// How the viewer relights under a map: automatic coverage, the sources' shadows by the LEDs'
// flows alone (no seconds spent recovering the scene's shape before the first frame).
relight::MapRelightOptions view_options(bool bright_sources) {
  relight::MapRelightOptions options;
  options.bright_sources = bright_sources;
  options.source_geometry = false;
  return options;
}

}  // namespace

ViewLighting environment_lighting(const physics::EnvironmentMap& map, double rotation_deg,
                                  const std::vector<capture::FieldLight>& leds,
                                  const EnvironmentNeeds& needs) {
  ViewLighting l;
  if (!leds.empty()) {
    if (needs.field_sources) {
      relight::SplitLighting split =
          relight::map_lighting(map, leds, rotation_deg, view_options(/*bright_sources=*/true));
      if (!split.sources.empty()) l.split = std::move(split);
    }
    // The whole map, sun included, for the sources that cannot add a bright source back (PCA).
    if (needs.whole_map_led_weights || !l.split) {
      l.led_irradiance_rgb =
          relight::map_lighting(map, leds, rotation_deg, view_options(/*bright_sources=*/false))
              .weights.irradiance_rgb;
    }
  }
  if (needs.model_lights) {
    relight::EnvironmentSampling sampling;
    sampling.covered_by_leds = capture::light_directions(leds);
    l.lights = relight::LightingForModels::environment(map, rotation_deg, sampling);
  }
  return l;
}

bool renders_bright_sources(const ViewLighting& lighting) {
  return lighting.split && relight::MapRelighter::renders_sources(*lighting.split);
}

BrightSourceLight::BrightSourceLight(const capture::ReflectanceField& field)
    : width_(field.width()),
      height_(field.height()),
      relighter_(std::make_unique<relight::MapRelighter>(field, view_options(true))) {}

BrightSourceLight::BrightSourceLight(const relight::PcaField& pca)
    : width_(pca.width()),
      height_(pca.height()),
      relighter_(std::make_unique<relight::MapRelighter>(pca, view_options(true))) {}

BrightSourceLight::~BrightSourceLight() = default;

void BrightSourceLight::add(const ViewLighting& lighting, Image& out) {
  if (renders_bright_sources(lighting)) relighter_->add_sources(*lighting.split, out);
}

bool BrightSourceLight::render(const ViewLighting& lighting, Image& out) {
  if (!renders_bright_sources(lighting)) return false;
  if (out.width != width_ || out.height != height_ || out.channels != 3) {
    out = Image(width_, height_, 3);
  } else {
    std::fill(out.pixels.begin(), out.pixels.end(), 0.0f);
  }
  relighter_->add_sources(*lighting.split, out);
  return true;
}

}  // namespace ls::viewer
