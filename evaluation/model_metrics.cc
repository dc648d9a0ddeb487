#include "evaluation/model_metrics.h"

#include <array>

namespace ls::evaluation {

double model_speckle(const relight::ModelMaps& maps) {
  const int width = maps.maps.width, height = maps.maps.height;
  long considered = 0, speckled = 0;
  for (int y = 1; y + 1 < height; ++y) {
    for (int x = 1; x + 1 < width; ++x) {
      const int own = int(maps.model(x, y));
      if (own == 0) continue;
      std::array<int, 5> votes{};
      int neighbours = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int model = int(maps.model(x + dx, y + dy));
          if ((dx == 0 && dy == 0) || model == 0) continue;
          ++votes[size_t(model)];
          ++neighbours;
        }
      }
      if (neighbours < 5) continue;
      ++considered;
      for (int m = 1; m < 5; ++m) {
        if (m != own && 2 * votes[size_t(m)] > neighbours) ++speckled;
      }
    }
  }
  return considered > 0 ? double(speckled) / double(considered) : 0.0;
}

relight::FitModel true_model(const physics::brdf::Material& material) {
  if (material.specular == physics::brdf::SpecularModel::kTorranceSparrow) {
    return relight::FitModel::kLambertTorranceSparrow;
  }
  if (material.specular != physics::brdf::SpecularModel::kNone)
    return relight::FitModel::kLambertPhong;
  return material.diffuse == physics::brdf::DiffuseModel::kOrenNayar ? relight::FitModel::kOrenNayar
                                                                     : relight::FitModel::kLambert;
}

RegionModels models_on(const relight::ModelMaps& maps, const std::vector<sim::SurfaceHit>& hits,
                       relight::FitModel model) {
  const int width = maps.maps.width, height = maps.maps.height;
  // hits is row-major, one per pixel (sim::trace_camera).
  auto material_at = [&](int x, int y) {
    return x < 0 || y < 0 || x >= width || y >= height ? -2
                                                       : hits[size_t(y) * width + x].material_index;
  };
  RegionModels out;
  for (const sim::SurfaceHit& h : hits) {
    if (!h.hit || true_model(h.material) != model) continue;
    bool interior = true;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        interior = interior && material_at(h.pixel_x + dx, h.pixel_y + dy) == h.material_index;
      }
    }
    if (!interior) continue;
    const relight::FitModel fitted = maps.model(h.pixel_x, h.pixel_y);
    if (fitted == relight::FitModel::kNone) continue;
    ++out.pixels;
    out.wrong += fitted != model;
  }
  return out;
}

}  // namespace ls::evaluation
