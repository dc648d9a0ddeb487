#pragma once
// Appearance edits on fitted model maps (relight/fit/fit.h), read from a JSON edit file that
// `lightstage relight --models MAPS.exr --edits EDITS.json` applies (the viewer will write the same
// file). Format (comments allowed; unknown keys are errors; every field optional unless noted):
//
//   {
//     "edits": [                                  // Applied in order, each to the maps as the
//       {                                         // edits before it left them.
//         "select": {                             // Required; "model", "material" and/or "mask"
//                                                 // (more than one: AND).
//           "model": "torrance_sparrow",          // "lambert", "oren_nayar", "torrance_sparrow"
//                                                 // (Lambert + TS lobe), "phong" (Lambert + Phong)
//           "material": 3,                        // A basis material (relight/fit/fit.h), 1-based:
//                                                 // the pixels whose main material it is.
//           "mask": "masks/sphere.png"            // Relative to the edit file; white (mean of RGB
//         },                                      // >= 0.5) = selected; the maps' size exactly.
//         "set_model": {                          // Applied first: replaces the model.
//           "model": "torrance_sparrow",          // Required. "lambert" drops any lobe and sigma;
//           "ks": 0.3, "roughness": 0.15          // TS needs ks >= 0, roughness in [0.02, 1];
//         },                                      // "phong": ks, "exponent" in [1, 1e4];
//                                                 // "oren_nayar": "sigma_rad" in [0, pi/2].
//         "albedo_tint": [1.0, 0.6, 0.6],         // Multiplies the diffuse albedo (each >= 0).
//         "roughness_scale": 2.0,                 // Multiplies the lobe's roughness (> 0).
//         "specular_scale": 0.5,                  // Multiplies k_s (>= 0).
//         "sigma_scale": 1.5                      // Multiplies Oren-Nayar sigma (>= 0).
//       }
//     ]
//   }
//
// Every edited parameter is clamped to its bounds: albedo to [0, 1] (a fitted albedo already
// above 1, possible on uncalibrated data, is never raised, only kept or lowered), sigma to
// [0, pi/2], k_s to >= 0, Torrance-Sparrow roughness to [0.02, 1], Phong's equivalent roughness
// sqrt(2 / (exponent + 2)) to the exponent range [1, 1e4]. Flagged pixels (no model) are never
// selected. Scales act only where the parameter exists (roughness and k_s on pixels with a lobe,
// sigma on Oren-Nayar pixels). The fit's confidence and residual channels are left as fitted.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "relight/fit/fit.h"

namespace ls {
class JsonReader;
}  // namespace ls

namespace ls::relight {

struct ModelSelection {
  std::optional<FitModel> model;
  int material = 0;                 // 1-based into ModelMaps::materials; 0: any.
  std::filesystem::path mask_file;  // As written in the edit file (empty: no mask).
  std::vector<uint8_t> mask;        // width x height, row-major, 1 = selected; empty: no mask.
};

struct ModelSwap {
  FitModel model = FitModel::kLambert;
  double sigma_rad = 0;        // Oren-Nayar.
  double ks = 0;               // Torrance-Sparrow, Phong.
  double roughness = 0.2;      // Torrance-Sparrow Beckmann m.
  double phong_exponent = 50;  // Phong.
};

struct ModelEdit {
  ModelSelection select;
  std::optional<ModelSwap> set_model;
  Eigen::Vector3d albedo_tint{1, 1, 1};
  double roughness_scale = 1;
  double specular_scale = 1;
  double sigma_scale = 1;
};

struct ModelEdits {
  std::string source;  // The edit file, for messages.
  std::vector<ModelEdit> edits;
};

// Reads and validates an edit file for maps of width x height (masks are loaded and checked
// here). InputErrors name the file and the field: "edits.json: edits[1].select.model: expected
// one of "lambert", ..., got string "glossy"".
ModelEdits read_model_edits(const std::filesystem::path& path, int width, int height);
// Same from text; masks are resolved against base_dir.
ModelEdits parse_model_edits(std::string_view json_text, const std::string& source,
                             const std::filesystem::path& base_dir, int width, int height);

// The edit file's name of a model ("lambert", "oren_nayar", "torrance_sparrow", "phong").
const char* edit_model_name(FitModel model);

// An edit file's "mask" value (`mask_field`: a path relative to base_dir, or absolute) read as a
// selection: width x height, row-major, 1 where the mean of the colour channels is >= 0.5. Its
// path as written goes to *mask_file. Errors (unreadable, wrong size) name the field.
std::vector<uint8_t> read_selection_mask(const JsonReader& mask_field,
                                         const std::filesystem::path& base_dir, int width,
                                         int height, std::filesystem::path* mask_file);

// Applies the edits in order; returns the number of pixels each edit selected. An edit that selects
// a material the maps do not have is an InputError naming the edit file and the field. `maps` may
// be a band of rows (read_model_map_rows) starting at row first_row of the masks' frame.
std::vector<int> apply_model_edits(const ModelEdits& edits, ModelMaps& maps, int first_row = 0);

}  // namespace ls::relight
