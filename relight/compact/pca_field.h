#pragma once
// PCA of the light dimension of a reflectance field, and the raw field as a
// CompactField.
//
// Every (pixel, channel) is a vector of L light samples v(l). PCA finds k light functions
// B(l, j) (orthonormal over the LEDs) and stores k coefficients per pixel and channel,
// C(x, j, c) = sum_l B(l, j) R(x, l, c), so that R(x, l, c) ~ sum_j B(l, j) C(x, j, c).
// Uncentred: the first function is close to the mean, and relighting stays one dot product.
//
// How: the L x L Gram matrix G = sum over samples of v v^T (double, accumulated over row tiles in
// parallel) and its eigen-decomposition. Why not an SVD of the 3N x L data matrix: at 512^2 x 150
// that matrix is 786k x 150 (0.9 GB in double) and a thin SVD costs several times the 3N L^2 flops
// of the Gram product, which runs as a blocked rank update; the L x L eigenproblem is then
// negligible (150^3). The Gram squares the condition number, but we only need eigenvalues down to
// the noise floor, ~1e-8 of the largest at most, well inside double precision.
//
// Rank from the noise floor: keeping component j costs its share of the noise (s2 per value, spread
// evenly over the L eigen-directions: s2 / L each) and leaving it out costs its signal, which is
// its eigenvalue minus that noise. So the error against the noise-free field is smallest when
// exactly the components whose eigenvalue per sample exceeds 2 s2 are kept, and the automatic k
// is the smallest k whose next component is at or below keep_above_noise x s2 (default 2): every
// component left out carries no more signal than noise. (The residual of the kept rank is then
// within a few times the noise of the L - k dimensions not kept, and, on the simulated scenes,
// k lands within 1.5x of the k that is best against the noise-free field: tests/compact.)
// s2 is the field's measured FieldNoise averaged over its values when measured. Otherwise it is
// estimated from the spectrum: with 3N >> L samples white noise spreads evenly over all L
// eigen-directions (Marchenko-Pastur: eigenvalues within (1 +- sqrt(L / 3N))^2 of 3N s2) while
// the signal of a reflectance field decays through them, so the smallest eigenvalues are the
// cleanest look at the noise: s2 = 10th percentile of the eigenvalues / (3N (1 - sqrt(L/3N))^2).
//
// Tiles: with tile_size > 0 each square tile of pixels gets its own basis (same k); the bases are
// amortised over the tile's pixels in bytes_per_pixel. lightstage bench compact measures global
// against tiled.
//
// Lighting between the LEDs: normalised Gaussian radial basis functions on the sphere over the LED
// directions (LightInterpolator), as the open RTI builders interpolate their per-light samples
// (relight/OpenLIME "rbf"); interpolating exactly at the LEDs, so a light on an LED is that LED.
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "relight/lighting/compact_field.h"
#include "relight/lighting/lighting.h"

namespace ls::relight {

// Turns distant lights into per-LED weights: a light along direction d contributes
// E * r_l(d) to LED l, where r(d) interpolates exactly at the LEDs (r_l(d_m) = delta_lm):
//   r(d)^T = psi(d)^T Psi^-1,  psi_i(d) = g_i(d) / sum_j g_j(d),  g_i(d) = exp(-a_i(d)^2 / 2 s^2)
// with a_i the angle to LED i and s = sigma (default: the mean nearest-neighbour angle). Far from
// every LED (below the dome) g vanishes and so does the light: what no LED covers contributes
// nothing, as in field relighting.
class LightInterpolator {
 public:
  LightInterpolator() = default;
  // Only the valid LEDs take part; the others get weight 0. Near LEDs count by their directions.
  explicit LightInterpolator(const std::vector<capture::FieldLight>& leds, double sigma_rad = 0.0);

  int num_leds() const { return int(dirs_.size()); }
  double sigma_rad() const { return sigma_rad_; }
  // r(d), one per LED (sums to about 1 inside the dome).
  void weights_at(const Eigen::Vector3d& dir, std::vector<double>& r) const;
  // 3 per LED: sum over lights of E(c) r_l(d).
  std::vector<float> led_irradiance(const LightingForModels& lights) const;

 private:
  std::vector<Eigen::Vector3d> dirs_;
  std::vector<int> active_;      // Indices of the valid LEDs.
  Eigen::MatrixXd psi_inverse_;  // Over the active LEDs.
  double sigma_rad_ = 0.0;
  double cutoff_cos_ = -1.0;  // Beyond 4 sigma a Gaussian is < 3e-4 of its peak: skipped.
};

// The raw field as a CompactField (the k = L end of the chart): relights with relight_into after
// turning the lights into LED weights (LightInterpolator).
class RawCompactField : public CompactField {
 public:
  // Refers to `field`, which must outlive this.
  explicit RawCompactField(const capture::ReflectanceField& field, double sigma_rad = 0.0);
  // Owns `field`.
  explicit RawCompactField(capture::ReflectanceField&& field, double sigma_rad = 0.0);
  std::string name() const override { return "raw field"; }
  int width() const override { return field_->width(); }
  int height() const override { return field_->height(); }
  double bytes_per_pixel() const override { return 12.0 * field_->num_lights(); }
  void relight_into(const LightingForModels& lights, Image& out) const override;

 private:
  void init(double sigma_rad);
  std::shared_ptr<const capture::ReflectanceField> field_;
  LightInterpolator interpolator_;
};

// How the automatic rank is chosen.
enum class PcaRankRule {
  // The noise floor (above): the rank the measurement noise justifies at the LEDs themselves.
  kNoiseFloor,
  // Relighting between LEDs: every 5th valid LED is held out, bases of every rank are built from
  // the rest, and the held-out samples are predicted through the RBF interpolation (at most ~64k
  // pixels, evenly strided); k is the smallest rank within held_out_tolerance_db of the lowest
  // held-out error. Every rank costs the same bytes per pixel, so this is the best held-out error
  // per byte at that distance from the best. Between LEDs a high rank mostly interpolates the
  // neighbours' noise and shadow edges, so this k is lower than the noise floor's.
  kHeldOutLights,
};

struct PcaOptions {
  PcaRankRule rank_rule = PcaRankRule::kNoiseFloor;
  int rank = 0;                   // 0: automatic from the noise floor (see above).
  int max_rank = 1000;            // Upper limit for the automatic rank (and clamp for `rank`).
  int tile_size = 0;              // 0: one global basis; else square tiles of this many pixels.
  double rbf_sigma_rad = 0.0;     // LightInterpolator's sigma; 0: mean nearest-neighbour angle.
  double keep_above_noise = 2.0;  // Keep components with eigenvalue / sample above this x s2.
  // kHeldOutLights: how far (in held-out PSNR) the chosen rank may be from the best; as export
  // openlime chooses its planes.
  double held_out_tolerance_db = 0.25;

  std::string validate() const;  // Empty when valid.
};

struct PcaSummary {
  int rank = 0;
  bool auto_rank = false;
  // Noise variance per value (field units^2) the rank was chosen against, and where it came from.
  double noise_variance = 0.0;
  bool noise_measured = false;
  std::string noise_method;
  // Mean square residual per value after k terms, k = 0..L (global basis; sum over tiles).
  std::vector<double> residual_ms;
  // kHeldOutLights: mean square error per held-out value for k = 0..K (empty otherwise).
  std::vector<double> held_out_ms;
  // The rank of the lowest held-out error (0: none measured).
  int held_out_best_rank() const;
  double mean_square = 0.0;  // Of all values.
  double seconds = 0.0;
  std::string to_string() const;
};

// One band's share of the pass that finds a PCA's basis: in a global basis the Gram matrix of
// each of its sub-bands (PcaField::band_alignment rows), in tiles those of its tiles (whole tile
// rows, row-major); and the sum of its positive values per sub-band or tile row (the noise floor).
// Summed in band order they give the whole field's, whichever process made each band's (MPI).
struct PcaBandGrams {
  int first_row = 0;
  std::vector<Eigen::MatrixXd> grams;
  std::vector<double> positive_sums;
};
// Visits every band's grams in order.
using PcaGramBands = std::function<void(const std::function<void(const PcaBandGrams&)>&)>;

class PcaField : public CompactField {
 public:
  PcaField() = default;
  static PcaField build(const capture::ReflectanceField& field, const PcaOptions& options,
                        PcaSummary* summary = nullptr);
  // The same over a field visited in bands (capture::FieldBands; a field larger than memory),
  // two passes (three with PcaRankRule::kHeldOutLights), each band a multiple of
  // band_alignment() rows but the last: the PCA of the whole field, bit for bit. `header` has the
  // field's size, lights and noise.
  static PcaField build(const capture::ReflectanceField& header, const capture::FieldBands& bands,
                        const PcaOptions& options, PcaSummary* summary = nullptr);
  static int band_alignment(int width, int height, const PcaOptions& options);
  // build() but for the coefficients (every pass over the bands but the last): the bases and
  // rank, for project_band to give the coefficients a band at a time (a field whose coefficients
  // are larger than memory: write() them from a file).
  static PcaField build_basis(const capture::ReflectanceField& header,
                              const capture::FieldBands& bands, const PcaOptions& options,
                              PcaSummary* summary = nullptr);
  // The same from every band's grams (made by this process or others); `bands` is read only for
  // the held-out rank rule.
  static PcaField build_basis(const capture::ReflectanceField& header, const PcaGramBands& grams,
                              const capture::FieldBands& bands, const PcaOptions& options,
                              PcaSummary* summary = nullptr);
  // A file's bytes (pca_field_io.cc's layout): its header, and its bases and coefficients (per
  // tile an L x k float basis, per pixel k x 3 float coefficients).
  static double header_bytes(int lights);
  static double data_bytes(int width, int height, int lights, int rank, int tile_size);
  // A band's grams: the band (rows of a field, whole sub-bands or tile rows as band_alignment
  // gives them) and the tile size asked (PcaOptions::tile_size).
  static PcaBandGrams band_grams(const capture::ReflectanceField& band, int tile_size);
  // The coefficients of a band's pixels, row-major (coefficients_per_row() floats a row), as
  // build() computes them.
  void project_band(const capture::ReflectanceField& band, float* coefs) const;
  std::size_t coefficients_per_row() const { return std::size_t(width_) * rank_ * 3; }
  // A basis (build_basis) kept with the summary of the passes that made it, as a checkpoint record
  // (lightstage/checkpoint_dir.h): a killed compress resumes after those passes. load_basis:
  // nullopt when the file is missing, unreadable or not a basis for `header`'s size and lights.
  void save_basis(const std::filesystem::path& file, const PcaSummary& summary) const;
  static std::optional<PcaField> load_basis(const std::filesystem::path& file,
                                            const capture::ReflectanceField& header,
                                            PcaSummary* summary);

  std::string name() const override;
  int width() const override { return width_; }
  int height() const override { return height_; }
  double bytes_per_pixel() const override;
  void relight_into(const LightingForModels& lights, Image& out) const override;
  // Relights from per-LED irradiance (3 per LED, as integrate_environment gives): the weights are
  // projected onto each tile's basis once (k x 3), then a k-term sum per pixel and channel.
  void relight_led_weights_into(const float* led_irradiance_rgb, Image& out) const;

  int rank() const { return rank_; }
  int num_lights() const { return int(lights_.size()); }
  // The field's lights as the file keeps them: led_id (the index), direction and validity.
  const std::vector<capture::FieldLight>& lights() const { return lights_; }
  int tile_size() const { return tile_size_; }
  // The reconstruction of one pixel's value under LED l.
  float reconstruct(int x, int y, int light, int c) const;
  // The reconstruction as a field, for what reads one (photometric stereo, bright sources:
  // relight/sources/field_sources.h): its header (the lights, no values), its rows in bands of
  // `rows`, and its image under LED l alone (width x height x 3, field units).
  capture::ReflectanceField header() const;
  capture::FieldBands reconstruction_bands(int rows = 64) const;
  std::vector<float> led_image(int led) const;

  // For GPU relighting (viewer/gpu_relight.cc), which does the per-pixel sum itself:
  // the number of tiles (1 for a global basis; row-major, tiles_across() per row of tiles),
  std::size_t num_tiles() const { return bases_.size(); }
  int tiles_across() const { return tiles_x(); }
  // the coefficients (per pixel, row-major from the top row: k x 3, [j * 3 + c]),
  const std::vector<float>& coefficients() const { return coefs_; }
  // and the per-LED irradiance (3 per LED) projected on each tile's basis, exactly as
  // relight_led_weights_into does it: per tile k x 3, [(t * k + j) * 3 + c].
  std::vector<float> project_led_weights(const float* led_irradiance_rgb) const;

  // Binary file (little-endian), documented in pca_field.cc: magic "LSPCA1\n", sizes, LED
  // directions and validity, the RBF sigma, the bases (float32) and coefficients (float32).
  void write(const std::filesystem::path& path) const;
  // The same file with row y's coefficients from rows(y, row) (coefficients_per_row() floats),
  // top to bottom: a basis from build_basis, its coefficients never held whole. Atomic: nothing
  // is left at `path` when rows throws.
  using CoefficientRows = std::function<void(int y, float* row)>;
  void write(const std::filesystem::path& path, const CoefficientRows& rows) const;
  // InputError naming the file and the field on anything malformed.
  static PcaField read(const std::filesystem::path& path);

 private:
  int tiles_x() const;
  int tile_of(int x, int y) const;

  int width_ = 0, height_ = 0, rank_ = 0, tile_size_ = 0;
  // What the file keeps of a field's lights: their directions and validity (led_id: the index).
  static std::vector<capture::FieldLight> kept_lights(
      const std::vector<capture::FieldLight>& lights);
  std::vector<capture::FieldLight> lights_;
  double sigma_rad_ = 0.0;
  std::vector<Eigen::MatrixXf> bases_;  // Per tile: L x k, orthonormal columns.
  std::vector<float> coefs_;            // Per pixel: k x 3, [j * 3 + c].
  LightInterpolator interpolator_;
};

}  // namespace ls::relight
