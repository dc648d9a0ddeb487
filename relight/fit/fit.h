#pragma once
// Per-pixel appearance fitting and model choice.
//
// For every pixel, starting from the photometric-stereo normal, fits
//   Lambert (albedo RGB), nested in both of
//   Oren-Nayar (albedo RGB, sigma; sigma = 0 is Lambert) and
//   Lambert + Torrance-Sparrow (albedo RGB, white k_s, Beckmann roughness; k_s = 0 is Lambert),
// and, as a comparison, Lambert + Phong (albedo RGB, white k_s, exponent). Every model also refines
// the normal (two offsets in the tangent plane of the photometric-stereo normal, i.e. two small
// angles: PS is biased for non-Lambertian surfaces, e.g. Oren-Nayar flattens the shading toward
// the viewer), so k = 5, 6, 7, 7 parameters.
//
// Solvers (FitSolver): by default each candidate is first fitted at the photometric-
// stereo normal with its albedos and k_s in closed form and its nonlinear parameter searched
// (relight/fit/profiled_fit.h); the best candidate by BIC, and any other that normal refinement
// could still make best, is then polished, normal included, by the bounded LM below. The other
// solver runs the LM on every candidate from the Lambert start (kEveryCandidateByLm).
//
// Each LM fit is bounded Levenberg-Marquardt (ceres::TinySolver through relight/fit/pixel_solver.h,
// autodiff Jets through physics/brdf.h) with the bounds built into the parametrisation:
// albedo = u^2, k_s = u^2, sigma = (pi/2) sigmoid(u), roughness = 0.02 + 0.98 sigmoid(u), Phong
// exponent = 1 + (1e4 - 1) sigmoid(u). A chosen fit whose solver stopped on max_iterations is
// kept but flagged kFitNotConverged.
//
// Samples: every valid light whose luminance is above the shadow threshold (NormalOptions), all
// three channels, each residual divided by its noise sigma (NoiseModel, from the measured value),
// so chi^2 = sum of squared residuals is chi^2-distributed with n - k degrees of freedom when the
// model is right. Samples at their light's saturation ceiling (capture/field.h) are left out too:
// they are lower bounds. Samples at or below the threshold are left out: a near-zero value where
// the model says "lit" is almost always a cast shadow (the models have no visibility term), and
// including it would bias albedo and normal; a near-zero value where the model says "unlit"
// carries almost no information. Samples above the threshold that the model predicts unlit (n.l
// <= 0) stay in and count against it.
//
// Model choice: BIC = chi^2 + k ln(n), n = number of residuals; the lowest BIC wins, ties go to the
// simpler model. A fit whose parameters or chi^2 are not finite is discarded (counted in the
// summary); a pixel with no finite fit is flagged, never NaN.
#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/exr_channels.h"
#include "lightstage/image.h"
#include "lightstage/progress.h"
#include "relight/fit/fit_shadows.h"
#include "relight/fit/normals.h"

namespace ls::relight {

enum class FitModel : int {
  kNone = 0,  // Flagged: no fit.
  kLambert = 1,
  kOrenNayar = 2,
  kLambertTorranceSparrow = 3,
  kLambertPhong = 4,
};
const char* to_string(FitModel model);
// The number of parameters BIC charges a model with: two normal angles (none when the normal is
// held), albedo r g b, and sigma (Oren-Nayar) or k_s and the lobe's shape (Torrance-Sparrow,
// Phong).
int model_parameters(FitModel model, bool refine_normal);

// Default bound on a lobe's k_s, shared with ModelRenderOptions (relight/fit/model_render.h).
inline constexpr double kDefaultMaxSpecularAlbedo = 2.0;

enum class FitSolver {
  kProfiled,            // Closed-form candidates, LM polish of the contenders (the default).
  kEveryCandidateByLm,  // LM on every candidate (kept as the comparison).
};
const char* to_string(FitSolver solver);

// How the scene's materials are modelled.
enum class FitMaterials {
  // Basis materials (relight/fit/basis_materials.h): the per-pixel fits are clustered into the
  // scene's few materials, each material fitted on all of its pixels' samples together, and each
  // pixel given the weights of at most two materials, unless its own per-pixel fit explains it
  // better by BIC (the per-pixel fit is then kept: material 0).
  kBasis,
  kPerPixel,  // Each pixel chooses its model alone (kept as the comparison).
};
const char* to_string(FitMaterials materials);

struct FitOptions {
  FitSolver solver = FitSolver::kProfiled;
  FitMaterials materials = FitMaterials::kBasis;
  // The most materials a scene is split into before materials that the data do not tell apart
  // (by the scene's BIC) are merged.
  int max_materials = 16;
  // Normals (used when fit_models estimates them) and the shadow threshold and noise model of the
  // fits: one NoiseModel for both.
  NormalOptions normals;
  bool fit_oren_nayar = true;
  bool fit_torrance_sparrow = true;
  bool fit_phong = false;  // Comparison only: off by default.
  // Torrance-Sparrow is multimodal in roughness: one LM start per entry, the best kept
  // (kEveryCandidateByLm; the profiled solver searches the roughness on a grid instead).
  std::vector<double> roughness_starts{0.08, 0.3};
  // Per LM fit; a chosen fit that stops on it is flagged kFitNotConverged.
  int max_iterations = 50;
  // Off: the normal is held at the given (photometric-stereo) normal and k drops by 2, e.g. for a
  // scene whose geometry does not change over time (relight/time/temporal_fit.h).
  bool refine_normal = true;
  // Fit each pixel again with the samples under the shadow threshold that its first fit predicts
  // dim and that agree with it (pixel::gather_with_dim_samples): a dark capture's pixels are
  // otherwise fitted to the samples noise lifted over the threshold, biased bright, and a dark
  // glossy pixel's normal to its highlight alone. Off by default (DiLiGenT: ball 1.71 -> 1.67 deg,
  // reading 12.15 -> 12.20; the ball's fit 27% slower); `fit --dim-samples`. For the temporal fit
  // see TemporalFitOptions::brdf.
  bool readmit_dim_samples = false;
  // A lobe fit (Torrance-Sparrow or Phong) with k_s above this is discarded and the pixel falls
  // back to a simpler model: k_s is the lobe's albedo (Fresnel folded in), at most about 1 for
  // calibrated data; 3e4..1e8 happen where no sample constrains the lobe (near silhouettes, under
  // clipping). 2 leaves margin for calibration error. Raise it for data in uncalibrated units.
  double max_specular_albedo = kDefaultMaxSpecularAlbedo;
  // View direction (unit, toward the camera) per pixel, row-major; empty = orthographic (0, 0, 1).
  std::vector<Eigen::Vector3d> view_dir_per_pixel;
  // Where normals.noise came from, stored with the maps (e.g. "measured: dark-frame pairs").
  std::string noise_source = "default NoiseModel";
  // Phase "fit", rows: called as rows finish, from TBB worker threads, concurrently: it must be
  // thread-safe (ProgressReporter::update is). Empty: no progress.
  ProgressFn progress;

  std::string validate() const;
  // Weighs the fit with the field's own measured noise (capture/noise_estimate.h) when it carries
  // one, and says so in noise_source; else keeps the defaults and says that.
  void use_noise_of(const capture::ReflectanceField& field);
};

// Channels of ModelMaps::maps, in order.
enum MapChannel : int {
  kMapNormalX = 0,
  kMapNormalY,
  kMapNormalZ,
  kMapAlbedoR,
  kMapAlbedoG,
  kMapAlbedoB,
  kMapSigma,       // Oren-Nayar sigma in radians (0 unless model = Oren-Nayar).
  kMapKs,          // Specular albedo (white), 0 for diffuse models.
  kMapRoughness,   // Beckmann m; for Phong the equivalent m = sqrt(2 / (exponent + 2)).
  kMapModel,       // FitModel as a number.
  kMapConfidence,  // BIC weight of the chosen model, exp(-BIC/2) normalised over the candidates.
  kMapResidual,    // Reduced chi^2 of the chosen model (about 1 when it explains the data).
  kMapFlags,       // NormalFlag bits | kFitFailed | kFitNotConverged.
  // Basis materials (FitMaterials::kBasis): the pixel's main material, 1-based into
  // ModelMaps::materials (0 = none: a per-pixel fit or no fit), its weight, and a second material
  // and weight (0 when the pixel is one material). The pixel's reflectance is
  // weight * material + weight2 * material2; the channels above hold its parameters.
  kMapMaterial,
  kMapMaterialWeight,
  kMapMaterial2,
  kMapMaterial2Weight,
  kMapChannelCount,
};
// Flag bits of kMapFlags beside the NormalFlag bits (relight/fit/normals.h); the codes are stored
// in maps on disk: never renumber.
inline constexpr int kFitFailed = 16;  // No model could be fitted (the pixel is not fitted).
// The chosen model's solver stopped on max_iterations: the pixel is fitted, but its parameters are
// where LM stopped, not at a minimum. 128, not 64: models_at_time (relight/time/temporal_render.h)
// carries kExtrapolated (64) in kMapFlags, and kTemporalNotConverged is this same bit.
inline constexpr int kFitNotConverged = 128;
// Basis materials: the pixel belongs to its material (kMapMaterial) but keeps its own fit's
// parameters, of the material's model, which explain its data better by BIC.
inline constexpr int kOwnParameters = 256;
// Basis materials: part of the pixel's lobe points where its samples show cast shadows (an
// occluder between it and some LEDs within the lobe); a render keeps the highlight out of them
// (ModelMaps::shadows).
inline constexpr int kLobeShadowed = 512;

// One basis material: a model and its parameters, the reflectance a pixel of weight 1 has.
struct Material {
  FitModel model = FitModel::kLambert;
  Eigen::Vector3d albedo{0, 0, 0};
  double sigma = 0;      // Oren-Nayar, radians.
  double ks = 0;         // Torrance-Sparrow, white.
  double roughness = 0;  // Torrance-Sparrow Beckmann m.
  int pixels = 0;        // Pixels whose main material it is.
  // The scene material it is part of (1-based): basis materials of one model and shape whose
  // pixels tile one region (a checker, a print) are one material with an albedo texture. Edits by
  // material select the whole scene material.
  int scene_material = 0;
};

// Where a fit's time went, wall-clock seconds, so that a slow case explains itself.
struct FitTimes {
  double noise = 0;       // The noise estimated from the data (0 when the field measured it).
  double normals = 0;     // Photometric stereo.
  double candidates = 0;  // Each pixel's candidate models fitted and one chosen.
  double materials = 0;   // Basis materials found and assigned (with their models' shadows).
  double shadows = 0;     // The per-pixel models' shadows (without basis materials).
  double writing = 0;     // The maps and previews written.
  double reading = 0;     // The field read, in bands (a whole field is read before any of this).
  void add(const FitTimes& part);
  std::string to_string() const;  // "noise 0.12 s, normals 0.31 s, ..."
};

struct FitSummary {
  int pixels = 0;
  int fitted = 0;
  int flagged = 0;
  // Pixels with no signal (kNoSignal: every sample 0, as outside a mask): neither fitted nor
  // flagged.
  int empty = 0;
  int per_model[5] = {0, 0, 0, 0, 0};   // Indexed by FitModel.
  int discarded_nonfinite_fits = 0;     // Individual model fits thrown away (not pixels).
  int discarded_implausible_lobes = 0;  // Lobe fits with k_s > max_specular_albedo (per model).
  int not_converged = 0;                // Fitted pixels flagged kFitNotConverged.
  int materials = 0;                    // Basis materials found (0: per-pixel fitting).
  int scene_materials = 0;              // Their scene materials (Material::scene_material).
  int material_pixels = 0;              // Fitted pixels explained by basis materials.
  double seconds = 0;
  FitTimes times;
  std::string to_string() const;
  // Adds the pixel counts and times of another part of the image (a band fitted on its own).
  void add(const FitSummary& part);
};

struct ModelMaps {
  Image maps;  // kMapChannelCount named channels: normal.x/y/z, albedo.r/g/b, sigma, ks, ...
  // Not stored in the file: read_model_maps fills only pixels/fitted/flagged/not_converged.
  FitSummary summary;
  // The noise model the fit weighted its residuals with (so kMapResidual can be read) and where it
  // came from; stored in the "lightstage:fit_noise" attribute.
  NoiseModel noise;
  std::string noise_source;
  // The basis materials kMapMaterial indexes (1-based); stored in the "lightstage:materials"
  // attribute. Empty for per-pixel fits.
  std::vector<Material> materials;
  // The LEDs each fitted pixel saw in cast shadow (relight/fit/fit_shadows.h), so that a model
  // render has the field's visibility; channels "shadow.N" of the file. Empty for maps read
  // from a file without those channels: every light then lights every pixel.
  FitShadows shadows;
  float at(int x, int y, MapChannel c) const { return maps.at(x, y, c); }
  FitModel model(int x, int y) const { return FitModel(int(maps.at(x, y, kMapModel))); }
};

// Estimates normals (options.normals) and fits every pixel.
ModelMaps fit_models(const capture::ReflectanceField& field, const FitOptions& options);
// Fits every pixel starting from given normals (flagged normals are not fitted).
ModelMaps fit_models(const capture::ReflectanceField& field, const NormalMap& normals,
                     const FitOptions& options);

// Fills maps.shadows over the rows of `field` (a band of rows of the frame from its first_row(), or
// the whole frame) from the fitted models in `maps`, whose row 0 is the frame's row
// maps_first_row; maps.shadows is sized to the maps and the field's lights first if it is not.
void measure_fit_shadows(const capture::ReflectanceField& field, const FitOptions& options,
                         int maps_first_row, ModelMaps& maps);

// Writes the maps as one EXR (float, named channels) and a PNG preview per map beside it:
// <stem>.normal.png (0.5 + 0.5 n), .albedo.png, .sigma.png (/ (pi/2)), .ks.png, .roughness.png,
// .model.png (model / 4), .confidence.png, .residual.png (log10(1 + r) / 2), .flags.png.
void write_model_maps(const std::filesystem::path& path, const ModelMaps& maps,
                      const ExrAttributes& attributes = {});

// The same file and previews written a band of rows at a time, top to bottom (a fit in bands of a
// field larger than memory): the same bytes as write_model_maps. `header` gives what
// the file's header holds (noise, materials, the shadows' LEDs and words); its rows are unused.
// Nothing is left at `path` before commit().
class ModelMapsWriter {
 public:
  // Which files: both, or one of them (two processes share the work under MPI).
  enum class Files { kMapsAndPreviews, kMaps, kPreviews };
  ModelMapsWriter(const std::filesystem::path& path, int width, int height, const ModelMaps& header,
                  const ExrAttributes& attributes = {}, Files files = Files::kMapsAndPreviews);
  ~ModelMapsWriter();
  ModelMapsWriter(const ModelMapsWriter&) = delete;
  ModelMapsWriter& operator=(const ModelMapsWriter&) = delete;
  // The next rows: band.maps and band.shadows of the same rows.
  void write_rows(const ModelMaps& band);
  void commit();

 private:
  std::unique_ptr<ImageRowWriter> maps_;
  std::vector<std::unique_ptr<PreviewRowWriter>> previews_;
  bool shadows_ = false;
};

// Reads what write_model_maps wrote, bit-exactly (channels found by name, in any order). Validates
// every channel: finite values, model in 0..4, flags an integer in 0..65535, unit normals and
// albedo/sigma/ks/roughness within their bounds on fitted pixels. Errors are InputErrors naming
// the file and the channel: "maps.exr: channel 'model': expected an integer in 0..4 at (3, 7),
// got 9".
ModelMaps read_model_maps(const std::filesystem::path& path);
// Rows [y0, y1) of the file (y1 < 0: to the last), checked as above (errors give the file's
// coordinates): a band of maps larger than memory; their summary counts the band's pixels.
ModelMaps read_model_map_rows(const std::filesystem::path& path, int y0, int y1);

// Channel names of ModelMaps::maps, indexed by MapChannel.
const std::vector<std::string>& model_map_channel_names();

}  // namespace ls::relight
