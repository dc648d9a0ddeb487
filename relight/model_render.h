#pragma once
// Relighting fitted BRDF models (relight/fit.h ModelMaps) instead of the reflectance field:
//   I(x) = sum_k f_r(x; w_k, w_o) * max(0, n . w_k) * E_k      (per channel, radiance out)
// over a set of distant light directions w_k (unit, toward the light, stage frame) with E_k the
// irradiance each delivers at normal incidence (radiance x solid angle of the patch it stands for).
// f_r is the pixel's fitted model (relight/brdf.h, cos not inside) with its fitted normal.
//
// The models have NO visibility: no cast shadows and no interreflection. A direction lights a
// pixel whenever it is above the pixel's tangent plane, so where the field shows a cast shadow (or
// a penumbra) a model render is brighter than field relighting or the truth. In exchange a model
// can be lit from directions no LED covers (below the dome) and by sources smaller than an LED's
// cell, and it can be edited (relight/model_edit.h).
//
// Two ways to turn an environment map into lights, both measured in tests/fit/model_render_test.cc:
//  * environment(): the map box-filtered onto a coarse lat-long grid (directions_width x /2), one
//    light per texel at its centre with E = mean radiance x exact texel solid angle. Converges to
//    the true integral as the grid gets finer; cost is linear in the number of non-black texels.
//  * led_cells(): one light per LED with E_l = the map integrated over LED l's Voronoi cell
//    (integrate_environment), exactly the lights field relighting uses, so the two renders differ
//    only by what the model gets wrong (shadows, misfit), not by how the map was sampled.
#include <Eigen/Core>
#include <vector>

#include "lightstage/image.h"
#include "relight/envmap.h"
#include "relight/fit.h"
#include "relight/light_cells.h"

namespace ls::relight {

// How environment() samples a map.
struct EnvironmentSampling {
  int directions_width =
      64;  // Lat-long grid of directions_width x directions_width/2 (even, >= 4).
  // When set, only directions within coverage_radius_rad (<= 0: the largest nearest-neighbour angle
  // between LEDs, as light_cells.h) of one of these LEDs are kept. The fit saw light only from the
  // dome, so outside it a lobe is extrapolated: a fit poorly constrained at a rim pixel can carry a
  // lobe aimed below the dome that no measurement bounds.
  std::vector<Eigen::Vector3d> covered_by_leds;
  double coverage_radius_rad = 0.0;
};

struct LightingForModels {
  std::vector<Eigen::Vector3f> dirs_in_stage;   // Unit, toward the light.
  std::vector<Eigen::Vector3f> irradiance_rgb;  // At normal incidence, per direction.

  // The map (rotated by rotation_deg about +Y, as for field relighting) box-filtered onto the
  // sampling's grid; black texels are dropped.
  static LightingForModels environment(const EnvironmentMap& map, double rotation_deg = 0.0,
                                       const EnvironmentSampling& sampling = {});
  // One light per LED: direction led_dirs[l], irradiance weights.irradiance_rgb[3l..3l+2]
  // (integrate_environment); LEDs with zero weight (dead ones) are dropped.
  static LightingForModels led_cells(const std::vector<Eigen::Vector3d>& led_dirs,
                                     const LightWeights& weights);
  // A single distant light: irradiance_rgb at normal incidence from dir_in_stage.
  static LightingForModels directional(const Eigen::Vector3d& dir_in_stage,
                                       const Eigen::Vector3d& irradiance_rgb);
};

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

// 3-channel linear radiance image the size of the maps. Rows in parallel (TBB); never NaN (the maps
// are finite, read_model_maps checks that). Throws InputError when the options do not fit the
// maps (view directions or fallback of the wrong size).
Image render_models(const ModelMaps& maps, const LightingForModels& lighting,
                    const ModelRenderOptions& options = {});

}  // namespace ls::relight
