// lightstage fit: reflectance field -> per-pixel BRDF model maps (EXR + PNG previews); lightstage
// normals: the photometric-stereo normals alone.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <vector>

#include "app/cli/commands.h"
#include "app/jobs/fit_job.h"
#include "app/jobs/ranks.h"
#include "lightstage/memory.h"
#include "lightstage/memory_option.h"

namespace ls::cli {

namespace fs = std::filesystem;

namespace {

// A fit weighed by the default noise model, not this camera's: said even under --quiet.
void warn_default_noise(const std::string& source, const relight::NoiseModel&) {
  if (source.starts_with("default")) {
    std::fprintf(stderr,
                 "warning: noise: %s; the weights and the shadow threshold are the simulated "
                 "camera's, not this data's\n",
                 source.c_str());
  }
}

void print_noise(const std::string& source, const relight::NoiseModel& noise) {
  std::fprintf(stderr, "noise: %s: variance = %.3g + %.3g * v\n", source.c_str(), noise.a, noise.b);
  warn_default_noise(source, noise);
}

// "read in bands of N rows split over R MPI ranks (...); peak memory M MiB".
void print_bands(int band_rows, int height, int ranks, int resumed_rows) {
  if (band_rows < height) {
    std::printf("  read in bands of %d rows", band_rows);
    if (ranks > 1) std::printf(" split over %d MPI ranks", ranks);
    if (resumed_rows > 0)
      std::printf(" (%d rows' fits taken from an interrupted run)", resumed_rows);
    std::printf("; ");
  } else {
    std::printf("  ");
  }
  std::printf("peak memory %.1f MiB\n", double(peak_resident_bytes()) / (1 << 20));
}

}  // namespace

int fit_field_file(const jobs::FitJobOptions& options, bool quiet) {
  // Under MPI rank 0 reports (its own share of the bands) and prints; the others are silent.
  quiet = quiet || !jobs::Ranks::world().root();
  const auto lock = lock_output(options.out);
  const jobs::FitJobSummary summary =
      jobs::fit(options, progress_printer(quiet), quiet ? warn_default_noise : print_noise);
  if (!jobs::Ranks::world().root()) return 0;
  const relight::FitSummary& s = summary.fit;
  std::printf("%s: %dx%d pixels, %d fitted, %d flagged", options.out.c_str(), summary.width,
              summary.height, s.fitted, s.flagged);
  if (s.empty > 0) std::printf(", %d with no signal (every sample 0, as outside a mask)", s.empty);
  std::printf("\n");
  for (int m = 1; m < 5; ++m) {
    if (m == int(relight::FitModel::kLambertPhong) && !options.phong) continue;
    std::printf("  %-26s %8d pixels (%.1f%% of fitted)\n", relight::to_string(relight::FitModel(m)),
                s.per_model[m], s.fitted > 0 ? 100.0 * s.per_model[m] / s.fitted : 0.0);
  }
  if (!summary.materials.empty()) {
    const bool textured = s.scene_materials < int(summary.materials.size());
    std::printf(
        "  %zu basis materials (%d scene materials%s) explain %d pixels (%.1f%% of fitted; the "
        "rest keep their own fit):\n",
        summary.materials.size(), s.scene_materials,
        textured ? ", those of one with an albedo texture tile one region" : "", s.material_pixels,
        s.fitted > 0 ? 100.0 * s.material_pixels / s.fitted : 0.0);
    for (size_t k = 0; k < summary.materials.size(); ++k) {
      const relight::Material& m = summary.materials[k];
      std::printf("    %2zu %-26s albedo %.3f %.3f %.3f", k + 1, relight::to_string(m.model),
                  m.albedo(0), m.albedo(1), m.albedo(2));
      if (m.model == relight::FitModel::kOrenNayar) std::printf(", sigma %.3f rad", m.sigma);
      if (m.model == relight::FitModel::kLambertTorranceSparrow) {
        std::printf(", ks %.3f, roughness %.3f", m.ks, m.roughness);
      }
      std::printf(" (%d pixels)", m.pixels);
      if (textured) std::printf(", scene material %d", m.scene_material);
      std::printf("\n");
    }
  }
  if (s.discarded_nonfinite_fits > 0) {
    std::printf("  %d individual model fits were not finite and were discarded\n",
                s.discarded_nonfinite_fits);
  }
  const double seconds = summary.seconds;
  std::printf("  %.2f s (normals + fit): %.0f pixels/s, %.0f fitted pixels/s\n", seconds,
              seconds > 0 ? s.pixels / seconds : 0.0, seconds > 0 ? s.fitted / seconds : 0.0);
  std::printf("  time: %s\n", s.times.to_string().c_str());
  std::printf("  noise: %s, variance = %.3g + %.3g * v\n", summary.noise_source.c_str(),
              summary.noise.a, summary.noise.b);
  print_bands(summary.band_rows, summary.height, summary.ranks, summary.resumed_rows);
  return 0;
}

namespace {

int fit_time_fields(const jobs::FitJobOptions& options, bool quiet) {
  // Under MPI rank 0 reports and prints; the others are silent.
  quiet = quiet || !jobs::Ranks::world().root();
  const auto lock = lock_output(options.out);
  const jobs::TemporalFitJobSummary summary = jobs::fit_over_time(
      options, progress_printer(quiet), quiet ? warn_default_noise : print_noise);
  if (!jobs::Ranks::world().root()) return 0;
  const relight::TemporalSummary& s = summary.fit;
  std::printf("%s: %dx%d pixels, %zu steps from %.1f s to %.1f s, %d fitted, %d flagged\n",
              options.out.c_str(), summary.width, summary.height, summary.step_times_s.size(),
              summary.step_times_s.front(), summary.step_times_s.back(), s.fitted, s.flagged);
  for (int m = 1; m < relight::kTemporalModelCount; ++m) {
    std::printf("  %-12s %8d pixels (%.1f%% of fitted)",
                relight::to_string(relight::TemporalModel(m)), s.per_model[m],
                s.fitted > 0 ? 100.0 * s.per_model[m] / s.fitted : 0.0);
    if (relight::TemporalModel(m) == relight::TemporalModel::kCurve && s.curve_families > 0) {
      std::printf(", %d curve families", s.curve_families);
    }
    if (relight::TemporalModel(m) == relight::TemporalModel::kSteps) {
      std::printf(
          ": the per-step fits interpolated, where no model predicted left-out steps better");
    }
    std::printf("\n");
  }
  std::printf(
      "  not fitted: %d without a normal (background, too few lit LEDs), %d without a "
      "usable step\n",
      s.no_normal, s.no_usable_step);
  std::printf(
      "  notes on fitted pixels: %d faster than sampling, %d with too few steps for a process, %d "
      "with a dropped step, %d degenerate (rendered from their nearest step)\n",
      s.faster_than_sampling, s.too_few_steps, s.step_dropped, s.degenerate);
  std::printf("  %.2f s: per-step BRDF fits %.2f s, temporal fits %.2f s (%.1f us/pixel)\n",
              summary.seconds, s.seconds_steps, s.seconds_temporal,
              s.pixels > 0 ? 1e6 * s.seconds_temporal / s.pixels : 0.0);
  print_bands(summary.band_rows, summary.height, summary.ranks, summary.resumed_rows);
  return 0;
}

}  // namespace

void add_fit_command(CLI::App& app) {
  auto options = std::make_shared<jobs::FitJobOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand(
      "fit",
      "Fit a BRDF model per pixel of a reflectance field: photometric-stereo normals, then "
      "Lambert, Oren-Nayar and Lambert + Torrance-Sparrow (and Lambert + Phong with --phong), "
      "the model chosen by BIC. Writes MAPS.exr (normal, albedo, sigma, ks, roughness, model, "
      "confidence, residual, flags, material ids and weights) and a PNG preview per map beside it "
      "(MAPS.materials.png: the basis materials); 'lightstage relight "
      "--models MAPS.exr' renders them.");
  cmd->add_option("field", options->field_file, "Reflectance field (.exr from 'lightstage build').")
      ->check(CLI::ExistingFile);
  cmd->add_option("--time", options->time_inputs,
                  "Time-varying fit: one field per time step (their scene_time_s), or a "
                  "directory of field_tNNN.exr. Writes temporal maps (process per pixel, rate, "
                  "onset, wet and dry parameters) for 'lightstage relight --time T --temporal'.")
      ->expected(1, -1)
      ->check(CLI::ExistingPath);
  cmd->add_option("--out", options->out, "Model maps to write (.exr).")->required();
  cmd->add_flag("--phong", options->phong, "Also fit Lambert + Phong (for comparison).");
  cmd->add_flag("--dim-samples", options->dim_samples,
                "Fit each pixel again with its samples under the shadow threshold that its first "
                "fit predicts dim: for a dark or underexposed capture (albedos not biased bright, "
                "a dark glossy pixel's normal not left to its highlight); slower. With --time: "
                "every step's fit and the normals.");
  cmd->add_option("--method", options->method,
                  "Photometric-stereo normals: robust (trimmed start + Tukey IRLS, ignores "
                  "highlights) or ls (weighted least squares).")
      ->check(CLI::IsMember({"robust", "ls"}))
      ->capture_default_str();
  cmd->add_option("--materials", options->materials,
                  "basis: cluster the per-pixel fits into the scene's few materials, fit each "
                  "material on all of its pixels, and give each pixel the weights of one or two "
                  "materials (its own fit kept where no material explains it); per-pixel: each "
                  "pixel chooses its model alone.")
      ->check(CLI::IsMember({"basis", "per-pixel"}))
      ->capture_default_str();
  add_memory_option(*cmd, options->memory,
                    "Fit: the band of the field fitted at once (read twice with basis materials); "
                    "with --time, every step's band and its fits together.");
  add_quiet_flag(*cmd, *quiet);
  cmd->callback([options, quiet] {
    if (const std::string problem = options->validate(); !problem.empty()) {
      throw CLI::ValidationError("fit", problem);
    }
    if (!options->time_inputs.empty()) {
      fit_time_fields(*options, *quiet);
    } else {
      fit_field_file(*options, *quiet);
    }
  });
}

}  // namespace ls::cli

namespace ls::cli {

void add_normals_command(CLI::App& app) {
  auto options = std::make_shared<jobs::NormalsJobOptions>();
  auto quiet = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "normals",
      "Photometric-stereo normals alone (no BRDF fit): normal, Lambertian albedo, confidence and "
      "flags per pixel in one EXR, with PNG previews; read in bands within --memory.");
  cmd->add_option("field", options->field_file, "Reflectance field (.exr).")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", options->out, "Normals file (.exr).")->required();
  cmd->add_option("--method", options->method,
                  "robust: iteratively reweighted, shadows and highlights left out; ls: least "
                  "squares over the lit samples.")
      ->check(CLI::IsMember({"robust", "ls"}))
      ->capture_default_str();
  add_memory_option(*cmd, options->memory, "Normals: the band of the field read at once.",
                    "512 MiB (each band is written as it is done: larger bands are no faster)");
  add_quiet_flag(*cmd, *quiet);
  cmd->callback([options, quiet] {
    if (const std::string problem = options->validate(); !problem.empty()) {
      throw CLI::ValidationError("normals", problem);
    }
    // Under MPI rank 0 reports and prints; the others are silent.
    const bool root = jobs::Ranks::world().root();
    const auto lock = lock_output(options->out);
    const jobs::NormalsJobSummary s =
        jobs::estimate_normals(*options, progress_printer(*quiet || !root));
    if (!root) return;
    const long with_signal = long(s.width) * s.height - s.empty_pixels;
    std::printf(
        "%s: %dx%d normals, %ld flagged (%.1f%% of the pixels with signal: too few lit lights, "
        "ill-conditioned or saturated)",
        options->out.c_str(), s.width, s.height, s.flagged_pixels,
        with_signal > 0 ? 100.0 * double(s.flagged_pixels) / double(with_signal) : 0.0);
    if (s.empty_pixels > 0) {
      std::printf(", %ld with no signal (every sample 0, as outside a mask)", s.empty_pixels);
    }
    std::printf("\n");
    std::printf("  %.2f s; noise: %s; read in bands of %d rows", s.seconds, s.noise_source.c_str(),
                s.band_rows);
    if (s.ranks > 1) std::printf(" split over %d MPI ranks", s.ranks);
    std::printf("; peak memory %.1f MiB\n", double(peak_resident_bytes()) / (1 << 20));
  });
}

}  // namespace ls::cli
