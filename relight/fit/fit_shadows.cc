#include "relight/fit/fit_shadows.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "relight/fit/pixel_solver.h"

namespace ls::relight {

FitShadows FitShadows::all_lit(std::vector<Eigen::Vector3f> led_dirs, int width, int height) {
  FitShadows out;
  const int words = words_for(int(led_dirs.size()));
  out.led_dirs_in_stage = std::move(led_dirs);
  out.words = Image(width, height, words);
  for (int w = 0; w < words; ++w) out.words.channel_names.push_back("shadow." + std::to_string(w));
  return out;
}

void FitShadows::pixel_words(int x, int y, uint32_t* out) const {
  const float* w = &words.pixels[(size_t(y) * words.width + x) * words.channels];
  for (int c = 0; c < words.channels; ++c) out[c] = uint32_t(w[c]);
}

double FitShadows::shadow(int x, int y, int led) const {
  const uint32_t word = uint32_t(words.at(x, y, led / kLedsPerWord));
  return double(level(&word - led / kLedsPerWord, led)) / kShadowLevels;
}

void FitShadows::set_pixel_words(int x, int y, const uint32_t* in) {
  float* w = &words.pixels[(size_t(y) * words.width + x) * words.channels];
  for (int c = 0; c < words.channels; ++c) w[c] = float(in[c]);
}

std::vector<int> nearest_leds(const std::vector<Eigen::Vector3f>& leds,
                              const std::vector<Eigen::Vector3f>& dirs) {
  std::vector<Eigen::Vector3d> unit;
  unit.reserve(leds.size());
  for (const Eigen::Vector3f& d : leds) unit.push_back(d.cast<double>());
  const DirectionIndex index(unit);
  std::vector<int> out;
  out.reserve(dirs.size());
  for (const Eigen::Vector3f& d : dirs) out.push_back(index.nearest(d.cast<double>().normalized()));
  return out;
}

std::vector<Eigen::Vector3f> led_dirs_of(const capture::ReflectanceField& field) {
  std::vector<Eigen::Vector3f> dirs;
  dirs.reserve(field.lights().size());
  for (const capture::FieldLight& light : field.lights()) {
    dirs.push_back(light.dir_in_stage.normalized().cast<float>());
  }
  return dirs;
}

void measure_fit_shadows(const capture::ReflectanceField& field, const FitOptions& options,
                         int maps_first_row, ModelMaps& maps) {
  const std::vector<capture::FieldLight>& lights = field.lights();
  const int width = maps.maps.width;
  LS_CHECK(field.width() == width && field.first_row() >= maps_first_row &&
               field.first_row() + field.height() <= maps_first_row + maps.maps.height,
           "led shadows: the field's rows lie outside the maps");
  if (maps.shadows.empty() || maps.shadows.led_dirs_in_stage.size() != lights.size()) {
    maps.shadows = FitShadows::all_lit(led_dirs_of(field), width, maps.maps.height);
  }
  const capture::ValidLights valid = capture::valid_lights(field);
  const NoiseModel& noise = options.normals.noise;
  const int words = maps.shadows.words.channels;
  const float max_ks = float(options.max_specular_albedo);
  const auto luma = [](const auto& v) { return luminance(v[0], v[1], v[2]); };
  tbb::parallel_for(tbb::blocked_range<int>(0, field.height()), [&](const auto& rows) {
    std::vector<uint32_t> bits(size_t(words), 0);
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const int frame_y = field.first_row() + y, map_y = frame_y - maps_first_row;
      for (int x = 0; x < width; ++x) {
        std::fill(bits.begin(), bits.end(), 0u);
        const float* m = &maps.maps.at(x, map_y, 0);
        const int model = int(m[kMapModel]);
        if (model > int(FitModel::kNone) && model <= int(FitModel::kLambertPhong)) {
          const Eigen::Vector3f n =
              Eigen::Vector3f(m[kMapNormalX], m[kMapNormalY], m[kMapNormalZ]).normalized();
          const Eigen::Vector3f wo =
              pixel::view_dir_at(options.view_dir_per_pixel, size_t(frame_y) * width + x)
                  .cast<float>();
          std::optional<capture::PixelLightDirs> dir_to;  // Near LEDs only: from this pixel.
          if (valid.near) dir_to.emplace(field, x, y);
          const float* px = field.pixel(x, y);
          for (size_t i = 0; i < valid.index.size(); ++i) {
            const int light = valid.index[i];
            const float* v = px + 3 * size_t(light);
            if (capture::is_saturated(lights[size_t(light)], v)) continue;
            const Eigen::Vector3f wi =
                (dir_to ? (*dir_to)(light) : valid.dirs_in_stage[i]).cast<float>();
            if (!(n.dot(wi) > 0)) continue;
            const double predicted = luma(model_radiance(m, wi, wo, max_ks));
            const double measured = luma(v);
            if (!(predicted - measured >
                  FitShadows::kShadowSigmas * std::sqrt(noise.variance(predicted))) ||
                !std::isfinite(measured)) {
              continue;
            }
            const double share = std::clamp(1 - measured / predicted, 0.0, 1.0);
            const auto level = uint32_t(std::lround(share * FitShadows::kShadowLevels));
            bits[size_t(light / FitShadows::kLedsPerWord)] |=
                level << (FitShadows::kBitsPerLed * (light % FitShadows::kLedsPerWord));
          }
        }
        maps.shadows.set_pixel_words(x, map_y, bits.data());
      }
    }
  });
}

}  // namespace ls::relight
