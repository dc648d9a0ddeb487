#include "viewer/view_lighting.h"

#include <algorithm>
#include <utility>

#include "relight/lighting/light_cells.h"

namespace ls::viewer {

ViewLighting environment_lighting(const relight::EnvironmentMap& map, double rotation_deg,
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
        std::vector<capture::FieldLight> lights;
        for (size_t l = 0; l < pca.led_dirs().size(); ++l) {
          lights.push_back({int(l), pca.led_dirs()[l], bool(pca.led_valid()[l])});
        }
        const capture::ReflectanceField header =
            capture::ReflectanceField::without_values(pca.width(), pca.height(), lights);
        // The reconstruction in bands of 64 rows: what photometric stereo reads.
        const capture::FieldBands bands = [&](const capture::BandVisitor& visit) {
          for (int y0 = 0; y0 < pca.height(); y0 += 64) {
            const int rows = std::min(64, pca.height() - y0);
            capture::ReflectanceField band(pca.width(), rows, lights);
            band.set_band(y0, pca.height());
            for (int y = 0; y < rows; ++y) {
              for (int x = 0; x < pca.width(); ++x) {
                float* v = band.pixel(x, y);
                for (int l = 0; l < int(lights.size()); ++l) {
                  for (int c = 0; c < 3; ++c) v[3 * l + c] = pca.reconstruct(x, y0 + y, l, c);
                }
              }
            }
            visit(band);
          }
        };
        return std::make_unique<relight::FieldSources>(header, bands, [&pca](int led) {
          std::vector<float> one_led(3 * size_t(pca.num_lights()), 0.0f);
          std::fill_n(one_led.begin() + 3 * long(led), 3, 1.0f);
          Image image;
          pca.relight_led_weights_into(one_led.data(), image);
          return image.pixels;
        });
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
