#pragma once
// Relighting fitted BRDF models (relight/fit/fit.h ModelMaps) instead of the reflectance field:
//   I(x) = sum_k f_r(x; w_k, w_o) * max(0, n . w_k) * E_k      (per channel, radiance out)
// over a set of distant light directions w_k (unit, toward the light, stage frame) with E_k the
// irradiance each delivers at normal incidence (radiance x solid angle of the patch it stands for).
// f_r is the pixel's fitted model (physics/brdf.h, cos not inside) with its fitted normal.
//
// Visibility comes from the fit (ModelMaps::shadows, relight/fit/fit_shadows.h): a direction
// whose nearest LED the pixel saw in cast shadow does not light it. Known at the dome's
// resolution: a shadow's edge between two LEDs falls on the boundary of their cells. Maps without
// shadows (older files) have no visibility: a direction lights a pixel whenever it is above the
// pixel's tangent plane. No interreflection. A model can be lit from directions no LED covers
// (below the dome: lit) and by sources smaller than an LED's cell, and it can be edited
// (relight/fit/model_edit.h).
//
// Two ways to turn an environment map into lights, both measured in
// tests/relight/fit/model_render_test.cc:
//  * environment(): the map box-filtered onto a coarse lat-long grid (directions_width x /2), one
//    light per texel at its centre with E = mean radiance x exact texel solid angle. Converges to
//    the true integral as the grid gets finer; cost is linear in the number of non-black texels.
//  * led_cells(): one light per LED with E_l = the map integrated over LED l's Voronoi cell
//    (integrate_environment), exactly the lights field relighting uses, so the two renders differ
//    only by what the model gets wrong (shadows, misfit), not by how the map was sampled.
#include <Eigen/Core>
#include <vector>

#include "lightstage/image.h"
#include "physics/brdf.h"
#include "physics/envmap.h"
#include "relight/fit/fit.h"
#include "relight/lighting/compact_field.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/lighting.h"

namespace ls::relight {

struct ModelRenderOptions {
  // View direction per pixel (unit, toward the camera), row-major, as in FitOptions; empty =
  // orthographic (0, 0, 1). Use the same as the fit.
  std::vector<Eigen::Vector3d> view_dir_per_pixel;
  // Flagged pixels (model kNone: background, too few lights, failed fits) render black unless this
  // image is given (same size, >= 3 channels), e.g. the field relit under the same lighting: then
  // they take its value, so a model render can be a drop-in for a field render.
  const Image* flagged_fallback = nullptr;
  // The lobe's k_s is clamped to this when rendering: the same bound fit_models applies
  // (FitOptions::max_specular_albedo), kept here for maps fitted with a higher bound or by older
  // versions, where a pixel near the silhouette whose lobe no sample constrains could get a
  // non-physical k_s (~3e4) that shines under directions between or below the LEDs. Infinity:
  // render the fit as it is.
  float max_specular_albedo = float(kDefaultMaxSpecularAlbedo);
};

// A fitted pixel's radiance toward wo (unit) lit from wi (unit, toward the light) by unit
// irradiance at normal incidence: f_r * max(0, n . wi) per channel; m: the pixel's map channels,
// k_s clamped to max_ks. 0 for a pixel without a normal or facing away.
Eigen::Vector3f model_radiance(const float* m, const Eigen::Vector3f& wi, const Eigen::Vector3f& wo,
                               float max_ks);

// A fitted pixel's BRDF (1/sr, cos not inside) per channel at local geometry g (cosines to its
// normal, which is not read): m, max_ks as model_radiance's. 0 for a pixel without a model.
Eigen::Vector3f model_brdf(const float* m, const physics::brdf::Geometry<float>& g, float max_ks);

// 3-channel linear radiance image the size of the maps. Rows in parallel (TBB); never NaN (the maps
// are finite, read_model_maps checks that). Throws InputError when the options do not fit the
// maps (view directions or fallback of the wrong size).
Image render_models(const ModelMaps& maps, const LightingForModels& lighting,
                    const ModelRenderOptions& options = {});

// The fitted analytic models (relight/fit/fit.h) as the most compact point: a normal, an RGB albedo
// and up to two lobe parameters per pixel, rendered by render_models with the fit's shadows. Size:
// the 7 parameters as float32 plus one byte for the model id = 29 bytes per pixel, and 3 bits per
// LED of shadows.
class ModelCompactField : public CompactField {
 public:
  explicit ModelCompactField(ModelMaps maps, ModelRenderOptions options = {})
      : maps_(std::move(maps)), options_(std::move(options)) {}
  std::string name() const override { return "models"; }
  int width() const override { return maps_.maps.width; }
  int height() const override { return maps_.maps.height; }
  double bytes_per_pixel() const override {
    return 7 * 4 + 1 +
           (maps_.shadows.empty()
                ? 0.0
                : FitShadows::kBitsPerLed / 8.0 * double(maps_.shadows.led_dirs_in_stage.size()));
  }
  void relight_into(const LightingForModels& lights, Image& out) const override {
    out = render_models(maps_, lights, options_);
  }
  const ModelMaps& maps() const { return maps_; }

 private:
  ModelMaps maps_;
  ModelRenderOptions options_;
};

}  // namespace ls::relight
