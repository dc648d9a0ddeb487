// lightstage fit: reflectance field -> per-pixel BRDF model maps (EXR + PNG previews).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <vector>

#include "capture/field.h"
#include "app/cli/commands.h"
#include "lightstage/errors.h"
#include "lightstage/progress.h"
#include "relight/fit/fit.h"
#include "relight/fit/normals.h"
#include "relight/time/temporal_fit.h"

namespace ls::cli {

namespace fs = std::filesystem;

int fit_field_file(const FitRequest& request) {
  const capture::ReflectanceField field = capture::read_field(request.field_file);
  relight::FitOptions options;
  options.fit_phong = request.phong;
  options.normals.method = request.method == "ls" ? relight::NormalMethod::kLeastSquares
                                                  : relight::NormalMethod::kRobust;
  // The noise model weights every residual and sets the shadow threshold: the field's own
  // measurement when it carries one; otherwise NoiseModel's defaults, which describe the simulated
  // 12-bit camera near mid exposure (and are ~3x conservative in sigma for its merged brackets,
  // which only makes model choice more cautious: tests/relight/fit/fit_test.cc).
  if (field.noise.measured) {
    options.normals.noise.a = field.noise.read_variance;
    options.normals.noise.b = field.noise.shot_variance_per_unit;
    options.noise_source =
        "measured" + (field.noise.method.empty() ? "" : " (" + field.noise.method + ")");
  } else {
    options.noise_source = "default NoiseModel (the field carries no measured noise)";
  }
  if (!request.quiet) {
    std::fprintf(stderr, "noise: %s: variance = %.3g + %.3g * v\n", options.noise_source.c_str(),
                 options.normals.noise.a, options.normals.noise.b);
  }
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError(request.field_file.string() + ": noise: " + error);
  }

  const auto start = std::chrono::steady_clock::now();
  if (!request.quiet) std::fprintf(stderr, "normals (photometric stereo)...\n");
  const relight::NormalMap normals = relight::estimate_normals(field, options.normals);
  ProgressReporter progress("fit", field.height(), request.quiet);
  options.progress = [&](long done, long) { progress.update(done); };
  relight::ModelMaps maps = relight::fit_models(field, normals, options);
  progress.done();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  relight::write_model_maps(request.out, maps);

  const relight::FitSummary& s = maps.summary;
  std::printf("%s: %dx%d pixels, %d fitted, %d flagged\n", request.out.c_str(), field.width(),
              field.height(), s.fitted, s.flagged);
  for (int m = 1; m < 5; ++m) {
    if (m == int(relight::FitModel::kLambertPhong) && !request.phong) continue;
    std::printf("  %-26s %8d pixels (%.1f%% of fitted)\n", relight::to_string(relight::FitModel(m)),
                s.per_model[m], s.fitted > 0 ? 100.0 * s.per_model[m] / s.fitted : 0.0);
  }
  if (s.discarded_nonfinite_fits > 0) {
    std::printf("  %d individual model fits were not finite and were discarded\n",
                s.discarded_nonfinite_fits);
  }
  std::printf("  %.2f s (normals + fit): %.0f pixels/s, %.0f fitted pixels/s\n", seconds,
              seconds > 0 ? s.pixels / seconds : 0.0, seconds > 0 ? s.fitted / seconds : 0.0);
  std::printf("  noise: %s, variance = %.3g + %.3g * v\n", options.noise_source.c_str(),
              options.normals.noise.a, options.normals.noise.b);
  return 0;
}

namespace {

// The time-step fields: files as given, or the field_t*.exr (else *.exr) files of a directory.
std::vector<fs::path> expand_time_inputs(const std::vector<fs::path>& inputs) {
  std::vector<fs::path> files;
  for (const fs::path& in : inputs) {
    if (!fs::is_directory(in)) {
      files.push_back(in);
      continue;
    }
    std::vector<fs::path> found, any;
    for (const auto& entry : fs::directory_iterator(in)) {
      if (entry.path().extension() != ".exr") continue;
      any.push_back(entry.path());
      if (entry.path().filename().string().rfind("field_t", 0) == 0) found.push_back(entry.path());
    }
    if (found.empty()) found = any;
    if (found.empty()) throw InputError(in.string() + ": expected field .exr files, found none");
    std::sort(found.begin(), found.end());
    files.insert(files.end(), found.begin(), found.end());
  }
  return files;
}

int fit_time_fields(const FitRequest& request, const std::vector<fs::path>& inputs) {
  const std::vector<fs::path> files = expand_time_inputs(inputs);
  std::vector<capture::ReflectanceField> fields;
  {
    ProgressReporter reading("read fields", long(files.size()), request.quiet);
    for (const fs::path& f : files) {
      fields.push_back(capture::read_field(f));
      reading.update(long(fields.size()));
    }
    reading.done();
  }
  relight::TemporalFitOptions options;
  options.brdf.normals.method = request.method == "ls" ? relight::NormalMethod::kLeastSquares
                                                       : relight::NormalMethod::kRobust;
  // The noise of the first field that measured it (same camera for every step).
  options.brdf.noise_source = "default NoiseModel (no field carries a measured noise)";
  for (const capture::ReflectanceField& f : fields) {
    if (!f.noise.measured) continue;
    options.brdf.normals.noise.a = f.noise.read_variance;
    options.brdf.normals.noise.b = f.noise.shot_variance_per_unit;
    options.brdf.noise_source =
        "measured" + (f.noise.method.empty() ? "" : " (" + f.noise.method + ")");
    break;
  }
  if (const std::string error = options.validate(); !error.empty()) {
    throw InputError(files.front().string() + ": noise: " + error);
  }
  if (!request.quiet) {
    std::fprintf(stderr, "%zu time steps, noise: %s\n", fields.size(),
                 options.brdf.noise_source.c_str());
  }
  const auto start = std::chrono::steady_clock::now();
  ProgressReporter progress("fit over time", long(fields.size() + 1) * fields.front().height(),
                            request.quiet);
  options.progress = [&](long done, long) { progress.update(done); };
  const relight::TemporalMaps maps = relight::fit_temporal(fields, options);
  progress.done();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  relight::write_temporal_maps(request.out, maps);
  const relight::TemporalSummary& s = maps.summary;
  std::printf("%s: %dx%d pixels, %zu steps from %.1f s to %.1f s, %d fitted, %d flagged\n",
              request.out.c_str(), maps.maps.width, maps.maps.height, maps.step_times_s.size(),
              maps.first_time_s(), maps.last_time_s(), s.fitted, s.flagged);
  for (int m = 1; m < relight::kTemporalModelCount; ++m) {
    std::printf("  %-12s %8d pixels (%.1f%% of fitted)\n",
                relight::to_string(relight::TemporalModel(m)), s.per_model[m],
                s.fitted > 0 ? 100.0 * s.per_model[m] / s.fitted : 0.0);
  }
  std::printf("  flagged: %d faster than sampling, %d too few steps, %d with a dropped step\n",
              s.faster_than_sampling, s.too_few_steps, s.step_dropped);
  std::printf("  %.2f s: per-step BRDF fits %.2f s, temporal fits %.2f s (%.1f us/pixel)\n",
              seconds, s.seconds_steps, s.seconds_temporal,
              s.pixels > 0 ? 1e6 * s.seconds_temporal / s.pixels : 0.0);
  return 0;
}

}  // namespace

void add_fit_command(CLI::App& app) {
  auto request = std::make_shared<FitRequest>();
  auto* cmd = app.add_subcommand(
      "fit",
      "Fit a BRDF model per pixel of a reflectance field: photometric-stereo normals, then "
      "Lambert, Oren-Nayar and Lambert + Torrance-Sparrow (and Lambert + Phong with --phong), "
      "the model chosen by BIC. Writes MAPS.exr (normal, albedo, sigma, ks, roughness, model, "
      "confidence, residual, flags) and a PNG preview per map beside it; 'lightstage relight "
      "--models MAPS.exr' renders them.");
  auto time_inputs = std::make_shared<std::vector<fs::path>>();
  cmd->add_option("field", request->field_file, "Reflectance field (.exr from 'lightstage build').")
      ->check(CLI::ExistingFile);
  cmd->add_option("--time", *time_inputs,
                  "Time-varying fit (issue 6): one field per time step (their scene_time_s), or a "
                  "directory of field_tNNN.exr. Writes temporal maps (process per pixel, rate, "
                  "onset, wet and dry parameters) for 'lightstage relight --time T --temporal'.")
      ->expected(1, -1)
      ->check(CLI::ExistingPath);
  cmd->add_option("--out", request->out, "Model maps to write (.exr).")->required();
  cmd->add_flag("--phong", request->phong, "Also fit Lambert + Phong (for comparison).");
  cmd->add_option("--method", request->method,
                  "Photometric-stereo normals: robust (trimmed start + Tukey IRLS, ignores "
                  "highlights) or ls (weighted least squares).")
      ->check(CLI::IsMember({"robust", "ls"}))
      ->capture_default_str();
  cmd->add_flag("--quiet", request->quiet, "No progress output.");
  cmd->callback([request, time_inputs] {
    if (!time_inputs->empty()) {
      if (!request->field_file.empty()) {
        throw CLI::ValidationError("fit", "give either a field or --time FIELDS..., not both");
      }
      fit_time_fields(*request, *time_inputs);
      return;
    }
    if (request->field_file.empty()) {
      throw CLI::ValidationError("fit", "a field (or --time FIELDS...) is required");
    }
    fit_field_file(*request);
  });
}

}  // namespace ls::cli
