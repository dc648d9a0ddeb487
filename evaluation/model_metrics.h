#pragma once
// How well fitted model maps (relight/fit/fit.h) hold together, against the simulator's truth:
// the speckle that per-pixel model choice leaves and the wrong models on surfaces whose
// true material is Lambertian.
#include <vector>

#include "relight/fit/fit.h"
#include "sim/scene.h"

namespace ls::evaluation {

// The fraction of fitted pixels whose model differs from the majority of their 3x3 neighbours:
// among pixels with at least 5 fitted neighbours of 8, those whose neighbours' most common model
// (held by more than half of them) is not their own.
double model_speckle(const relight::ModelMaps& maps);

// The true model of a material (Lambert, Oren-Nayar, Lambert + Torrance-Sparrow or Phong).
relight::FitModel true_model(const physics::brdf::Material& material);

struct RegionModels {
  int pixels = 0;  // Fitted pixels whose true material is the region's.
  int wrong = 0;   // Of them, fitted with a model other than the true one.
  double wrong_fraction() const { return pixels > 0 ? double(wrong) / pixels : 0.0; }
};
// Over the hits (sim::trace_camera, one per pixel) whose true model is `model`, inside their
// material's region (the 3x3 neighbours hit the same material: an edge pixel's footprint mixes
// two materials): how many got another model.
RegionModels models_on(const relight::ModelMaps& maps, const std::vector<sim::SurfaceHit>& hits,
                       relight::FitModel model);

}  // namespace ls::evaluation
