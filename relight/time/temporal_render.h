#pragma once
// Time-varying BRDFs at any time (relight/time/temporal_fit.h): the per-pixel BRDF at scene time t,
// between, before or beyond the captured steps, rendered with relight/fit/model_render.h, and time
// edits (speed up or slow down a process per region; transfer a process from one region to
// another, as in the paper's effect transfer).
//
// Edit file (JSON, comments allowed, unknown keys are errors; masks relative to the file, white =
// selected, the maps' size):
//   {
//     "time": [                                    // Applied in order.
//       { "select": {"mask": "stroke.png", "model": "exponential"},   // "model" and/or "mask";
//         "rate_scale": 2.0 },                     // model: constant|exponential|sigmoid|dust.
//                                                  // The process runs rate_scale times faster
//                                                  // from the first step: rate x s, onset moved
//                                                  // to first + (onset - first) / s.
//       { "select": {"mask": "red_plane.png"},     // Target.
//         "transfer_from": {"mask": "blue_paint.png"} }   // Source (same selection syntax).
//     ]
//   }
// Transfer: the source region's process (the model that most of its fitted pixels chose, and for
// curves the family most of those follow; rate and onset: medians over those pixels) takes its
// endpoints relative to its own end state (a process's dry parameters, a curve's state at the last
// captured step), medians over those pixels (ratios for the albedo channels, differences for
// sigma, k_s, roughness) to each target pixel's own end state: the target moves from
// where it ends as the source moves from where it ends; clamped to bounds. (For a process source
// its end state is its dry endpoint: dry = the target's, wet = dry x wet/dry or dry + wet - dry.)
// A source region with no varying pixel is an InputError naming the edit.
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "relight/time/temporal_fit.h"

namespace ls::relight {

// ModelMaps at scene time t: model Oren-Nayar + Torrance-Sparrow is not a FitModel, so the maps
// hold the parameters with model = kLambertTorranceSparrow where k_s > 0, else kOrenNayar;
// render_temporal renders both lobes. kMapFlags carries kExtrapolated (temporal_fit.h) when t is
// outside [first step, last step] on a fitted, non-constant pixel.
struct TemporalState {
  ModelMaps maps;
  int extrapolated_pixels = 0;
};
TemporalState models_at_time(const TemporalMaps& maps, double time_s);

// Renders the temporal maps at time t under the lighting: the diffuse (Oren-Nayar) and the lobe
// (Torrance-Sparrow) parts through render_models, summed; a kSteps pixel as the blend of its two
// neighbouring steps' renders (models_at_time holds its blended parameters instead, one BRDF for
// what takes parameters). 3-channel radiance, never NaN.
Image render_temporal(const TemporalMaps& maps, double time_s, const LightingForModels& lighting,
                      const ModelRenderOptions& options = {}, int* extrapolated_pixels = nullptr);

struct TemporalSelection {
  std::optional<TemporalModel> model;
  std::filesystem::path mask_file;
  std::vector<uint8_t> mask;  // width x height, 1 = selected; empty: no mask.
};

struct TemporalEdit {
  TemporalSelection select;
  double rate_scale = 1.0;
  std::optional<TemporalSelection> transfer_from;
};

struct TemporalEdits {
  std::string source;
  std::vector<TemporalEdit> edits;
};

TemporalEdits read_temporal_edits(const std::filesystem::path& path, int width, int height);
TemporalEdits parse_temporal_edits(std::string_view json_text, const std::string& source,
                                   const std::filesystem::path& base_dir, int width, int height);
// Applies the edits in order; returns the number of pixels each edit changed.
std::vector<int> apply_temporal_edits(const TemporalEdits& edits, TemporalMaps& maps);

// The same on maps read in bands of rows (relight --temporal on maps larger than memory): what
// each transfer takes from its source region (the medians of its varying process over the whole
// maps, as the edits before it left them), from passes over every band; then each band edited.
struct TemporalTransfer {
  TemporalModel model = TemporalModel::kNone;
  int family = 0;   // kCurve: the family most of the source's curve pixels follow.
  double seen = 1;  // kCurve: the median of their kTCurveSeen.
  double rate = 0, onset = 0;
  double change_dry[kTemporalParamCount] = {}, change_wet[kTemporalParamCount] = {};
};
// Visits every band of the maps in order, read afresh (its rows start at first_row).
using TemporalMapsBands =
    std::function<void(const std::function<void(TemporalMaps& band, int first_row)>&)>;
std::vector<std::optional<TemporalTransfer>> temporal_transfers(const TemporalEdits& edits,
                                                                const TemporalMapsBands& bands);
std::vector<int> apply_temporal_edits(const TemporalEdits& edits,
                                      const std::vector<std::optional<TemporalTransfer>>& transfers,
                                      TemporalMaps& band, int first_row);

}  // namespace ls::relight
