// lightstage fit: reflectance field -> per-pixel BRDF model maps (EXR + PNG previews).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <memory>

#include "capture/field.h"
#include "lightstage/cli/commands.h"
#include "lightstage/errors.h"
#include "lightstage/progress.h"
#include "relight/fit.h"
#include "relight/normals.h"

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
  // which only makes model choice more cautious: tests/fit/fit_test.cc).
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

void add_fit_command(CLI::App& app) {
  auto request = std::make_shared<FitRequest>();
  auto* cmd = app.add_subcommand(
      "fit",
      "Fit a BRDF model per pixel of a reflectance field: photometric-stereo normals, then "
      "Lambert, Oren-Nayar and Lambert + Torrance-Sparrow (and Lambert + Phong with --phong), "
      "the model chosen by BIC. Writes MAPS.exr (normal, albedo, sigma, ks, roughness, model, "
      "confidence, residual, flags) and a PNG preview per map beside it; 'lightstage relight "
      "--models MAPS.exr' renders them.");
  cmd->add_option("field", request->field_file, "Reflectance field (.exr from 'lightstage build').")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", request->out, "Model maps to write (.exr).")->required();
  cmd->add_flag("--phong", request->phong, "Also fit Lambert + Phong (for comparison).");
  cmd->add_option("--method", request->method,
                  "Photometric-stereo normals: robust (trimmed start + Tukey IRLS, ignores "
                  "highlights) or ls (weighted least squares).")
      ->check(CLI::IsMember({"robust", "ls"}))
      ->capture_default_str();
  cmd->add_flag("--quiet", request->quiet, "No progress output.");
  cmd->callback([request] { fit_field_file(*request); });
}

}  // namespace ls::cli
