#include "relight/fit/noise_choice.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "lightstage/image.h"
#include "relight/fit/model_render.h"

namespace ls::relight {

namespace {

constexpr int kHoldOutEvery = 4;  // Lights with index % 4 == 1 are held out.
// The estimate's level first: ties keep it.
constexpr double kVarianceScales[] = {1, 1.0 / 4, 4, 1.0 / 16, 16};
constexpr int kChoicePixels = 2048;  // Every k-th pixel of the sample, at most this many.
// The thinned pixels are packed into rows of this many: the fits run in parallel over rows (one
// row of 2,048 pixels kept the five trial fits on one core).
constexpr long kThinnedWidth = 64;

// Every `stride`-th pixel of `sample`, packed row by row (the last row's remainder stays zero: no
// signal), with only the lights `kept`.
capture::ReflectanceField thinned(const capture::ReflectanceField& sample, long stride,
                                  const std::vector<int>& kept) {
  std::vector<capture::FieldLight> lights;
  lights.reserve(kept.size());
  for (const int l : kept) lights.push_back(sample.lights()[size_t(l)]);
  const long pixels = long(sample.width()) * sample.height();
  const long count = (pixels + stride - 1) / stride;
  const long width = std::min(count, kThinnedWidth);
  capture::ReflectanceField out(int(width), int((count + width - 1) / width), lights);
  for (long p = 0; p < pixels; p += stride) {
    const float* from = sample.pixel(int(p % sample.width()), int(p / sample.width()));
    const long i = p / stride;
    float* to = out.pixel(int(i % width), int(i / width));
    for (size_t k = 0; k < kept.size(); ++k) {
      for (int c = 0; c < 3; ++c) to[3 * k + c] = from[3 * size_t(kept[k]) + c];
    }
  }
  return out;
}

void score_held_out(const capture::ReflectanceField& sample, const std::vector<int>& held_out,
                    const ModelMaps& maps, float max_ks, NoiseCandidate& candidate) {
  const Eigen::Vector3f wo(0, 0, 1);  // As the fits: the sample's pixels have no place.
  double sum = 0;
  long count = 0;
  for (int y = 0; y < sample.height(); ++y) {
    for (int x = 0; x < sample.width(); ++x) {
      if (maps.model(x, y) == FitModel::kNone) continue;
      const float* m = maps.maps.pixels.data() +
                       (std::size_t(y) * std::size_t(maps.maps.width) + std::size_t(x)) *
                           std::size_t(maps.maps.channels);
      for (const int l : held_out) {
        const capture::FieldLight& light = sample.lights()[size_t(l)];
        const float* v = sample.pixel(x, y) + 3 * size_t(l);
        const float measured = luminance(v);
        if (!std::isfinite(measured) || capture::is_saturated(light, v)) continue;
        const Eigen::Vector3f predicted =
            model_radiance(m, light.dir_in_stage.cast<float>(), wo, max_ks);
        sum += std::abs(double(measured) - double(luminance(predicted.data())));
        ++count;
      }
    }
  }
  candidate.held_out_samples = count;
  candidate.held_out_error = count > 0 ? sum / double(count) : INFINITY;
}

}  // namespace

std::string describe_noise_choice(int index, double held_out_error) {
  char text[160];
  std::snprintf(text, sizeof text,
                "unweighted, the estimate's variance at the median lit value x%g (held-out error "
                "%.3g, best of %zu)",
                kVarianceScales[index], held_out_error, std::size(kVarianceScales));
  return text;
}

NoiseChoice choose_noise_by_held_out_lights(const capture::ReflectanceField& sample,
                                            const FitOptions& options, const NoiseModel& estimate) {
  std::vector<int> kept, held_out;
  for (int l = 0; l < sample.num_lights(); ++l) {
    if (!sample.lights()[size_t(l)].valid) continue;
    (l % kHoldOutEvery == 1 ? held_out : kept).push_back(l);
  }
  // The median lit value: where the unweighted candidates take the estimate's variance.
  std::vector<float> lit;
  const double dark = 4 * std::sqrt(estimate.a);
  for (int y = 0; y < sample.height(); ++y) {
    for (int x = 0; x < sample.width(); ++x) {
      for (const int l : kept) {
        const float value = luminance(sample.pixel(x, y) + 3 * size_t(l));
        if (value > dark) lit.push_back(value);
      }
    }
  }
  double typical = 0;
  if (!lit.empty()) {
    std::nth_element(lit.begin(), lit.begin() + long(lit.size() / 2), lit.end());
    typical = lit[lit.size() / 2];
  }
  NoiseChoice choice;
  for (const double scale : kVarianceScales) {
    choice.candidates.push_back({{(estimate.a + estimate.b * typical) * scale, 0}});
  }
  std::vector<int> every_light(size_t(sample.num_lights()));
  std::iota(every_light.begin(), every_light.end(), 0);
  const long stride =
      std::max(1L, (long(sample.width()) * sample.height() + kChoicePixels - 1) / kChoicePixels);
  const capture::ReflectanceField scored = thinned(sample, stride, every_light);
  const capture::ReflectanceField train = thinned(sample, stride, kept);
  FitOptions fit = options;
  fit.materials = FitMaterials::kPerPixel;
  fit.progress = {};
  fit.view_dir_per_pixel.clear();  // The sample's pixels come from all over the frame.
  for (size_t k = 0; k < choice.candidates.size(); ++k) {
    NoiseCandidate& candidate = choice.candidates[k];
    fit.normals.noise = candidate.model;
    const ModelMaps maps = fit_models(train, fit);
    score_held_out(scored, held_out, maps, float(options.max_specular_albedo), candidate);
    if (candidate.held_out_error < choice.best().held_out_error) choice.chosen = int(k);
  }
  return choice;
}

}  // namespace ls::relight
