#pragma once
// Fit a reflectance field (per-pixel normals and BRDF models) or a series of fields over time
// (time-varying models), weighted by the noise the capture measured.
#include <filesystem>
#include <string>
#include <vector>

#include "app/jobs/job.h"
#include "lightstage/memory.h"
#include "relight/fit/fit.h"
#include "relight/time/temporal_fit.h"

namespace ls::jobs {

struct FitJobOptions {
  std::filesystem::path field_file;
  // Time-varying fit: one field per time step, or directories of field_tNNN.exr (else *.exr).
  std::vector<std::filesystem::path> time_inputs;
  std::filesystem::path out;
  bool phong = false;               // Also fit Lambert + Phong (comparison).
  std::string method = "robust";    // Photometric-stereo normals: "robust" or "ls".
  std::string materials = "basis";  // "basis" or "per-pixel" (relight::FitMaterials).
  // Readmit the dim samples (relight::FitOptions::readmit_dim_samples), --time's steps too.
  bool dim_samples = false;
  // For the field (capture::FieldStream::band_rows): a field larger is fitted in bands of rows,
  // read twice with basis materials (fits, blends). --time: for every step's field and fits
  // together (relight/time/time_bands.h).
  MemoryBudget memory;
  std::string validate() const;
  std::string to_json() const;  // Recorded in the maps (kOptionsAttribute).
};

struct FitJobSummary {
  relight::FitSummary fit;
  std::vector<relight::Material> materials;  // Basis materials found (none: per-pixel).
  int width = 0, height = 0;
  std::string noise_source;
  relight::NoiseModel noise;
  double seconds = 0.0;  // Normals and fits.
  int band_rows = 0;     // Rows of a band (the height: the whole field at once).
  int resumed_rows = 0;  // Rows whose fits an earlier, killed run had finished (BandCheckpoints).
  int ranks = 1;         // Processes the bands were split over (MPI); rank 0 wrote the maps.
};

struct TemporalFitJobSummary {
  relight::TemporalSummary fit;
  int width = 0, height = 0;
  std::vector<double> step_times_s;
  std::string noise_source;
  double seconds = 0.0;
  int band_rows = 0;     // As FitJobSummary's.
  int resumed_rows = 0;  // Rows whose processes an earlier, killed run had fitted.
  int ranks = 1;
};

// Says which noise weighs the fit (before it starts); then the fit runs.
using NoiseNoticeFn = std::function<void(const std::string& source, const relight::NoiseModel&)>;

// Throws InputError for bad options or inputs.
FitJobSummary fit(const FitJobOptions& options, const ProgressFn& progress = {},
                  const NoiseNoticeFn& noise_notice = {});
TemporalFitJobSummary fit_over_time(const FitJobOptions& options, const ProgressFn& progress = {},
                                    const NoiseNoticeFn& noise_notice = {});

// lightstage normals: photometric-stereo normals alone (relight/fit/normals.h), with their
// Lambertian albedo, confidence and flags, weighted by the field's measured noise; the field read
// in bands within `memory` and the file written a band at a time, whatever its size.
struct NormalsJobOptions {
  std::filesystem::path field_file;
  std::filesystem::path out;      // An EXR: normal.x/y/z, albedo.r/g/b, confidence, flags.
  std::string method = "robust";  // "robust" or "ls".
  MemoryBudget memory;            // As FitJobOptions'.
  std::string validate() const;
};

struct NormalsJobSummary {
  int width = 0, height = 0;
  long flagged_pixels = 0;
  long empty_pixels = 0;  // No signal (relight::kNoSignal: every sample 0, as outside a mask).
  std::string noise_source;
  double seconds = 0.0;
  int band_rows = 0;
  int ranks = 1;  // Processes the bands were split over (MPI); rank 0 wrote the file.
};

// The channels of the normals file, in order.
const std::vector<std::string>& normals_channel_names();
NormalsJobSummary estimate_normals(const NormalsJobOptions& options,
                                   const ProgressFn& progress = {});

}  // namespace ls::jobs
