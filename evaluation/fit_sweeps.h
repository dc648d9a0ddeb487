#pragma once
// Failure sweeps for photometric-stereo normals and per-pixel BRDF fits: how the
// estimates degrade along one axis at a time, and whether they stay finite, in bounds and flagged.
//
// Each sweep point synthesises a field from the simulator's ground truth (three regions with known
// normals and materials: matte Lambert, rough Oren-Nayar, glossy Lambert + Torrance-Sparrow; three
// spheres, or three coplanar tilted strips for the grazing axis), the noise-free one-light images
// plus Gaussian noise from the fit's NoiseModel, degrades it along the axis, then runs
// least-squares and robust normals (relight/fit/normals.h) and the fits with BIC model choice
// (relight/fit/fit.h, from the robust normals), and scores every surface pixel against the truth.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "lightstage/progress.h"

namespace ls::evaluation {

enum class SweepAxis {
  kNoise,                // Noise sigma as a multiple of the default NoiseModel's (fits told it).
  kLedCount,             // LEDs on a Fibonacci dome (down to below the fits' min_lights).
  kLightDirectionError,  // Degrees: every LED direction the fits are told is rotated this much.
  kShadowedFraction,     // Fraction of the azimuth around each pixel's normal behind a wall.
  kSaturation,           // Fraction of the field's positive samples clipped (brightest first).
  kDeadLeds,             // Fraction of the LEDs marked invalid (dead).
  kGrazingNormals,       // Degrees between the surface normal and the view direction.
};
inline constexpr SweepAxis kAllSweepAxes[] = {SweepAxis::kNoise,
                                              SweepAxis::kLedCount,
                                              SweepAxis::kLightDirectionError,
                                              SweepAxis::kShadowedFraction,
                                              SweepAxis::kSaturation,
                                              SweepAxis::kDeadLeds,
                                              SweepAxis::kGrazingNormals};
const char* to_string(SweepAxis axis);   // "noise", "led_count", ... (CSV and file names).
const char* axis_label(SweepAxis axis);  // "noise sigma / default", ... (chart axes).

struct FitSweepOptions {
  int width = 48;  // Camera pixels; the scene spans 3:1, so keep width = 3 * height.
  int height = 16;
  int leds = 80;  // LEDs of the dome on every axis but kLedCount.
  uint64_t seed = 1;
  bool quick = false;  // Three values per axis instead of five to nine.
  std::vector<SweepAxis> axes{std::begin(kAllSweepAxes), std::end(kAllSweepAxes)};
  ProgressFn progress;  // Phase "fit sweeps", points.

  std::vector<double> values(SweepAxis axis) const;
  std::string validate() const;  // Empty when valid.
};

// One estimator's normal error over the surface pixels it did not flag.
struct NormalScore {
  std::optional<double> mean_deg, p95_deg;  // Empty when every surface pixel is flagged.
  double flagged_fraction = 0;              // Of the surface pixels.
};

struct SweepPoint {
  SweepAxis axis = SweepAxis::kNoise;
  double value = 0;
  int surface_pixels = 0;
  NormalScore least_squares, robust, fit;
  // Fit parameters, median relative (or absolute, sigma) error over unflagged pixels of the
  // region whose material has that parameter and where the fit chose the true model.
  std::optional<double> albedo_rel, sigma_deg, ks_rel, roughness_rel;
  std::optional<double>
      model_accuracy;              // Fraction of unflagged surface pixels with the true model.
  int unflagged_gross_errors = 0;  // Unflagged surface pixels with a fitted normal > 30 deg off.
  // Unflagged surface pixels with a fitted albedo or k_s above 1: in the fit's bounds (u^2, no
  // upper limit) but more light out than in: a failure nobody was told about.
  int unflagged_implausible = 0;
  // NaN, values outside the maps' declared ranges, or a kNone pixel without flags: must be 0.
  int invalid_outputs = 0;
  std::string first_invalid;  // The first such pixel and its values, for the report.
  double least_squares_seconds = 0, robust_seconds = 0;  // Normals.
  double fit_seconds = 0;
  double fit_pixels_per_second = 0;
};

std::vector<SweepPoint> run_fit_sweeps(const FitSweepOptions& options);

// One row per point; empty cells where a score is empty.
void write_fit_sweeps_csv(const std::filesystem::path& csv, const std::vector<SweepPoint>& points);

}  // namespace ls::evaluation
