#include "viewer/view_lighting.h"

#include <algorithm>
#include <utility>

#include "relight/lighting/light_cells.h"

namespace ls::viewer {

ViewLighting environment_lighting(const physics::EnvironmentMap& map, double rotation_deg,
                                  const std::vector<Eigen::Vector3d>& led_dirs,
                                  const std::vector<bool>& led_valid,
                                  const EnvironmentNeeds& needs) {
  ViewLighting l;
  if (!led_dirs.empty()) {
    if (needs.field_sources) {
      std::vector<capture::FieldLight> leds;
      leds.reserve(led_dirs.size());
      for (size_t i = 0; i < led_dirs.size(); ++i)
        leds.push_back({int(i), led_dirs[i], i >= led_valid.size() || led_valid[i]});
      relight::SplitLighting split =
          relight::split_lighting(map, leds, rotation_deg, /*coverage_rad=*/0.0, /*split=*/true);
      if (!split.sources.empty()) l.split = std::move(split);
    }
    // The whole map, sun included, for the sources that cannot add a compact source back (PCA).
    if (needs.whole_map_led_weights || !l.split) {
      l.led_irradiance_rgb =
          relight::integrate_environment(map, led_dirs, rotation_deg, 0.0, led_valid)
              .irradiance_rgb;
    }
  }
  if (needs.model_lights) {
    relight::EnvironmentSampling sampling;
    sampling.covered_by_leds = led_dirs;
    l.lights = relight::LightingForModels::environment(map, rotation_deg, sampling);
  }
  return l;
}

bool renders_compact_sources(const ViewLighting& lighting) {
  if (!lighting.split) return false;
  return std::any_of(lighting.split->sources.begin(), lighting.split->sources.end(),
                     [](const relight::PlacedSource& s) { return s.triangle.has_value(); });
}

CompactSourceLight::CompactSourceLight(const capture::ReflectanceField& field)
    : width_(field.width()),
      height_(field.height()),
      make_([&field] { return std::make_unique<relight::FieldSources>(field); }) {}

CompactSourceLight::CompactSourceLight(const relight::PcaField& pca)
    : width_(pca.width()), height_(pca.height()), make_([&pca] {
        return std::make_unique<relight::FieldSources>(
            pca.header(), pca.reconstruction_bands(),
            [&pca](int led) { return pca.led_image(led); });
      }) {}

const relight::FieldSources& CompactSourceLight::sources() {
  if (!sources_) sources_ = make_();
  return *sources_;
}

void CompactSourceLight::add(const ViewLighting& lighting, Image& out) {
  if (renders_compact_sources(lighting)) sources().add(*lighting.split, out);
}

bool CompactSourceLight::render(const ViewLighting& lighting, Image& out) {
  if (!renders_compact_sources(lighting)) return false;
  if (out.width != width_ || out.height != height_ || out.channels != 3) {
    out = Image(width_, height_, 3);
  } else {
    std::fill(out.pixels.begin(), out.pixels.end(), 0.0f);
  }
  sources().add(*lighting.split, out);
  return true;
}

}  // namespace ls::viewer
