#pragma once
// Internal to the viewer library: prefiltered lighting for the models source
// (ModelShading::kPrefiltered, viewer/gpu_models.cc), built on the CPU from the distant lights.
#include <array>
#include <cstdint>
#include <vector>

#include "relight/fit/model_render.h"

namespace ls::viewer::model_prefilter {

inline constexpr int kPrefilterWidth = 64, kPrefilterHeight = 32;  // Lat-long, envmap.h convention.
inline constexpr int kPrefilterLevels = 8;
// Beckmann m per level: the first about the lights' spacing (a 64-wide grid is 0.1 rad apart,
// the Beckmann reflection lobe is sqrt(2) m wide), then roughly x1.5 a level.
inline constexpr float kLevelRoughness[kPrefilterLevels] = {0.05f, 0.075f, 0.11f, 0.17f,
                                                            0.25f, 0.38f,  0.6f,  1.0f};
inline constexpr int kLobeAlbedoSize = 32;  // Table over cos_o and m, each 0..1 in 32 steps.

// Directional albedo of the lobes under unit radiance, integral of f cos_i over the hemisphere
// (1/k_s), tabulated at cos_o = (i / 31)^2 (x) and m = j / 31 (y; m >= 0.01); RGBA: r Torrance-
// Sparrow, g Phong with exponent 2/m^2 - 2 clamped to [1, 1e4] as the shader, b Oren-Nayar's
// B factor under uniform light (depends on cos_o only). Importance sampled
// on a 64 x 64 stratified grid: the Beckmann half vector for Torrance-Sparrow, cos^n about the
// mirror direction for Phong.
const std::vector<float>& lobe_albedo_table();

// FNV-1a over the lights: rebuild the prefiltered lighting only when they changed.
uint64_t fingerprint(const relight::LightingForModels& lights);

struct PrefilteredLighting {
  std::array<float, 27> sh_irradiance{};  // 9 RGB coefficients of E(n), A_l folded in.
  std::vector<float> levels;  // [level][row][column] RGBA radiance, row 0 the top (zenith).
};

// The SH irradiance and the prefiltered radiance stack of the lights.
PrefilteredLighting prefilter(const relight::LightingForModels& lights);

}  // namespace ls::viewer::model_prefilter
