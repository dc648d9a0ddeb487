// lightstage relight: field (or fitted model maps, optionally edited) + environment maps -> relit
// images (EXR + PNG previews + contact sheet).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <set>

#include "capture/field.h"
#include "app/cli/commands.h"
#include "lightstage/errors.h"
#include "lightstage/progress.h"
#include "relight/lighting/envmap.h"
#include "relight/fit/fit.h"
#include "relight/lighting/light_cells.h"
#include "relight/fit/model_edit.h"
#include "relight/fit/model_render.h"
#include "relight/lighting/relight.h"
#include "relight/time/temporal_render.h"

namespace ls::cli {

namespace fs = std::filesystem;

namespace {

// Output name of a map and rotation: the map's stem, its folder when two maps share a stem, and
// the rotation when there is one.
std::string output_name(const fs::path& map_path, double rotation, bool several_rotations,
                        std::set<std::string>& used_names) {
  std::string name = map_path.stem().string();
  if (used_names.count(name)) name = map_path.parent_path().filename().string() + "_" + name;
  if (several_rotations || rotation != 0.0) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "_rot%03d", int(std::lround(rotation)));
    name += buf;
  }
  used_names.insert(name);
  return name;
}

RelitOutput write_relit(const RelightRequest& request, const std::string& name, Image& relit) {
  relit.channel_names = {"R", "G", "B"};
  write_exr(request.out_dir / (name + ".exr"), relit);
  const double stops = request.auto_exposure ? auto_exposure_stops(relit) : request.exposure_stops;
  const fs::path png = request.out_dir / (name + ".png");
  write_png_preview(png, relit, stops);
  return {png, name};
}

// --models: the fitted maps (edited when asked) rendered under each map; a field, when given too,
// fills the pixels the fit flagged.
std::vector<RelitOutput> relight_models_file(const RelightRequest& request) {
  relight::ModelMaps maps = relight::read_model_maps(request.models_file);
  const int width = maps.maps.width, height = maps.maps.height;
  if (!request.edits_file.empty()) {
    const relight::ModelEdits edits = relight::read_model_edits(request.edits_file, width, height);
    const std::vector<int> counts = relight::apply_model_edits(edits, maps);
    if (!request.quiet) {
      for (size_t i = 0; i < counts.size(); ++i) {
        std::fprintf(stderr, "  %s: edits[%zu] changed %d pixels\n",
                     request.edits_file.filename().c_str(), i, counts[i]);
      }
    }
  }
  std::optional<capture::ReflectanceField> field;
  std::vector<Eigen::Vector3d> dirs;
  std::vector<bool> valid;
  if (!request.field_file.empty()) {
    field = capture::read_field(request.field_file);
    if (field->width() != width || field->height() != height) {
      throw InputError(request.field_file.string() + ": size: expected " + std::to_string(width) +
                       "x" + std::to_string(height) + " (the size of " +
                       request.models_file.string() + "), got " + std::to_string(field->width()) +
                       "x" + std::to_string(field->height()));
    }
    for (const auto& light : field->lights()) {
      dirs.push_back(light.dir_in_stage);
      valid.push_back(light.valid);
    }
  }
  const double coverage_rad = request.coverage_deg * M_PI / 180.0;
  // With a field, the models get the light the field gets (the dome's coverage): the fit saw no
  // other, and a lobe aimed below the dome is not bounded by any measurement.
  relight::EnvironmentSampling sampling;
  sampling.directions_width = request.directions_width;
  sampling.covered_by_leds = dirs;
  sampling.coverage_radius_rad = coverage_rad;
  fs::create_directories(request.out_dir);

  std::vector<RelitOutput> outputs;
  std::set<std::string> used_names;
  Image fallback;
  relight::ModelRenderOptions options;
  const bool with_light = request.light_dir.size() == 3;
  ProgressReporter progress("relight",
                            long(request.maps.size() * request.rotations_deg.size()) + with_light,
                            request.quiet);
  long done = 0;
  if (with_light) {
    // The field cannot be lit from an arbitrary direction: flagged pixels stay black here.
    const Eigen::Vector3d dir(request.light_dir[0], request.light_dir[1], request.light_dir[2]);
    Image relit = relight::render_models(
        maps, relight::LightingForModels::directional(dir, Eigen::Vector3d(1, 1, 1)));
    outputs.push_back(write_relit(request, "light", relit));
    progress.update(++done, "light");
  }
  for (const auto& map_path : request.maps) {
    const relight::EnvironmentMap map = relight::EnvironmentMap::load(map_path);
    for (double rotation : request.rotations_deg) {
      const auto t0 = std::chrono::steady_clock::now();
      const relight::LightingForModels lighting =
          relight::LightingForModels::environment(map, rotation, sampling);
      if (field) {
        const relight::LightWeights weights =
            relight::integrate_environment(map, dirs, rotation, coverage_rad, valid);
        relight::relight_into(*field, weights.irradiance_rgb.data(), fallback);
        options.flagged_fallback = &fallback;
      }
      const auto t1 = std::chrono::steady_clock::now();
      Image relit = relight::render_models(maps, lighting, options);
      const auto t2 = std::chrono::steady_clock::now();
      const std::string name =
          output_name(map_path, rotation, request.rotations_deg.size() > 1, used_names);
      outputs.push_back(write_relit(request, name, relit));
      progress.update(++done, name);
      if (!request.quiet) {
        std::fprintf(stderr, "  %s: lights %.1f ms (%zu directions%s), model render %.1f ms\n",
                     name.c_str(), std::chrono::duration<double, std::milli>(t1 - t0).count(),
                     lighting.dirs_in_stage.size(),
                     field ? " within the dome; field for flagged pixels" : " over the sphere",
                     std::chrono::duration<double, std::milli>(t2 - t1).count());
      }
    }
  }
  progress.done();
  return outputs;
}

// --temporal T.exr --time S: the time-varying models of 'lightstage fit --time' at scene time S
// (time edits from --edits: relight/time/temporal_render.h), rendered as --models renders.
std::vector<RelitOutput> relight_temporal_file(const RelightRequest& request,
                                               const fs::path& temporal_file, double time_s) {
  relight::TemporalMaps maps = relight::read_temporal_maps(temporal_file);
  if (!request.edits_file.empty()) {
    const relight::TemporalEdits edits =
        relight::read_temporal_edits(request.edits_file, maps.maps.width, maps.maps.height);
    const std::vector<int> counts = relight::apply_temporal_edits(edits, maps);
    for (size_t i = 0; i < counts.size() && !request.quiet; ++i) {
      std::fprintf(stderr, "  %s: time[%zu] changed %d pixels\n",
                   request.edits_file.filename().c_str(), i, counts[i]);
    }
  }
  fs::create_directories(request.out_dir);
  relight::EnvironmentSampling sampling;
  sampling.directions_width = request.directions_width;
  std::vector<RelitOutput> outputs;
  std::set<std::string> used_names;
  int extrapolated = 0;
  char suffix[32];
  std::snprintf(suffix, sizeof suffix, "_t%.0fs", time_s);
  if (request.light_dir.size() == 3) {
    const Eigen::Vector3d dir(request.light_dir[0], request.light_dir[1], request.light_dir[2]);
    Image relit = relight::render_temporal(
        maps, time_s, relight::LightingForModels::directional(dir, Eigen::Vector3d(1, 1, 1)), {},
        &extrapolated);
    outputs.push_back(write_relit(request, std::string("light") + suffix, relit));
  }
  ProgressReporter progress(
      "relight at t", long(request.maps.size() * request.rotations_deg.size()), request.quiet);
  long done = 0;
  for (const auto& map_path : request.maps) {
    const relight::EnvironmentMap map = relight::EnvironmentMap::load(map_path);
    for (double rotation : request.rotations_deg) {
      Image relit = relight::render_temporal(
          maps, time_s, relight::LightingForModels::environment(map, rotation, sampling), {},
          &extrapolated);
      const std::string name =
          output_name(map_path, rotation, request.rotations_deg.size() > 1, used_names) + suffix;
      outputs.push_back(write_relit(request, name, relit));
      progress.update(++done, name);
    }
  }
  progress.done();
  std::printf("t = %.1f s (captured %.1f .. %.1f s)%s\n", time_s, maps.first_time_s(),
              maps.last_time_s(),
              extrapolated > 0 ? ": EXTRAPOLATED beyond the captured steps" : "");
  if (extrapolated > 0) {
    std::printf("  %d varying pixels extrapolated (flag %d in their model maps)\n", extrapolated,
                relight::kExtrapolated);
  }
  return outputs;
}

}  // namespace

std::vector<RelitOutput> relight_field_file(const RelightRequest& request) {
  if (!request.models_file.empty()) return relight_models_file(request);
  const capture::ReflectanceField field = capture::read_field(request.field_file);
  std::vector<Eigen::Vector3d> dirs;
  std::vector<bool> valid;
  for (const auto& light : field.lights()) {
    dirs.push_back(light.dir_in_stage);
    valid.push_back(light.valid);
  }
  const double coverage_rad = request.coverage_deg * M_PI / 180.0;
  fs::create_directories(request.out_dir);

  std::vector<RelitOutput> outputs;
  std::set<std::string> used_names;  // Maps from different folders may share a file name.
  Image relit;
  ProgressReporter progress("relight", long(request.maps.size() * request.rotations_deg.size()),
                            request.quiet);
  long done = 0;
  for (const auto& map_path : request.maps) {
    const relight::EnvironmentMap map = relight::EnvironmentMap::load(map_path);
    for (double rotation : request.rotations_deg) {
      const auto t0 = std::chrono::steady_clock::now();
      const relight::LightWeights weights =
          relight::integrate_environment(map, dirs, rotation, coverage_rad, valid);
      const auto t1 = std::chrono::steady_clock::now();
      relight::relight_into(field, weights.irradiance_rgb.data(), relit);
      const auto t2 = std::chrono::steady_clock::now();

      const std::string name =
          output_name(map_path, rotation, request.rotations_deg.size() > 1, used_names);
      outputs.push_back(write_relit(request, name, relit));
      progress.update(++done, name);
      if (!request.quiet) {
        std::fprintf(stderr,
                     "  %s: light weights %.1f ms, relight %.1f ms; %.2f%% of the map's light "
                     "falls outside the dome's coverage and is not represented\n",
                     name.c_str(), std::chrono::duration<double, std::milli>(t1 - t0).count(),
                     std::chrono::duration<double, std::milli>(t2 - t1).count(),
                     100.0 * weights.uncovered_fraction());
      }
    }
  }
  progress.done();
  return outputs;
}

void add_relight_command(CLI::App& app) {
  auto request = std::make_shared<RelightRequest>();
  auto exposure = std::make_shared<double>(0.0);
  auto* cmd = app.add_subcommand(
      "relight",
      "Relight a reflectance field under lat-long HDR environment maps (.exr, .hdr): each LED "
      "stands for its spherical Voronoi cell of directions, I = sum_l R_l E_l. Or, with --models, "
      "render the per-pixel BRDF models of 'lightstage fit' (edited with --edits) under the maps. "
      "Writes NAME.exr (linear) and NAME.png (tone-mapped preview) per map and rotation, and "
      "contact_sheet.png.");
  cmd->add_option("field", request->field_file,
                  "Reflectance field (.exr from 'lightstage build'); optional with --models.")
      ->check(CLI::ExistingFile);
  cmd->add_option("--models", request->models_file,
                  "Render fitted model maps (.exr from 'lightstage fit') instead of the field. "
                  "The models have no shadows; pixels the fit flagged are black. With a field "
                  "too, flagged pixels come from the field relit under the same map, and the "
                  "models get only the light the dome covers, as the field does.")
      ->check(CLI::ExistingFile);
  auto* edits_opt =
      cmd->add_option("--edits", request->edits_file,
                      "Edit file (JSON: selections by model or mask, albedo tint, roughness / "
                      "specular / sigma scales, model swaps) applied to --models before rendering.")
          ->check(CLI::ExistingFile);
  cmd->add_option("--directions", request->directions_width,
                  "With --models: the map is integrated on a lat-long grid of N x N/2 directions.")
      ->check(CLI::Range(4, 4096))
      ->capture_default_str();
  cmd->add_option("--env", request->maps, "Environment map(s), lat-long .exr or .hdr.")
      ->check(CLI::ExistingFile);
  cmd->add_option("--light", request->light_dir,
                  "With --models: also render under one distant light from direction X Y Z "
                  "(stage frame, toward the light) of unit irradiance, as light.exr/png.")
      ->expected(3);
  cmd->add_option("--rotate", request->rotations_deg,
                  "Rotation(s) of the map about the vertical axis, degrees.")
      ->capture_default_str();
  auto* exp_opt = cmd->add_option("--exposure", *exposure,
                                  "Preview exposure in stops (default: automatic per image).");
  cmd->add_option("--coverage-deg", request->coverage_deg,
                  "Dome coverage radius around each LED, degrees (0: automatic).")
      ->capture_default_str();
  cmd->add_option("--out", request->out_dir, "Output directory.")->required();
  cmd->add_flag("--quiet", request->quiet, "No progress output.");
  auto temporal_file = std::make_shared<fs::path>();
  auto time_s = std::make_shared<double>(0.0);
  auto* temporal_opt =
      cmd->add_option("--temporal", *temporal_file,
                      "Temporal maps from 'lightstage fit --time', rendered at --time (with "
                      "--edits: a time edit file, see relight/time/temporal_render.h).")
          ->check(CLI::ExistingFile);
  auto* time_opt = cmd->add_option("--time", *time_s,
                                   "With --temporal: scene time in seconds (any time; "
                                   "outside the captured steps it is flagged).");
  cmd->callback([request, exposure, exp_opt, edits_opt, temporal_file, time_s, temporal_opt,
                 time_opt] {
    if (temporal_opt->count() > 0) {
      if (time_opt->count() == 0) throw CLI::ValidationError("--temporal", "give --time T too");
      if (request->maps.empty() && request->light_dir.empty()) {
        throw CLI::ValidationError("--env", "give at least one map (or --light)");
      }
      request->auto_exposure = exp_opt->count() == 0;
      request->exposure_stops = *exposure;
      const auto outputs = relight_temporal_file(*request, *temporal_file, *time_s);
      write_contact_sheet(request->out_dir / "contact_sheet.png", outputs,
                          "temporal: " + temporal_file->filename().string());
      return;
    }
    if (request->field_file.empty() && request->models_file.empty()) {
      throw CLI::ValidationError("relight", "give a field, --models MAPS.exr, or both");
    }
    if (request->maps.empty() && (request->models_file.empty() || request->light_dir.empty())) {
      throw CLI::ValidationError("--env", "give at least one map (or --light with --models)");
    }
    if (!request->light_dir.empty() && request->models_file.empty()) {
      throw CLI::ValidationError("--light", "a directional light renders models: give --models");
    }
    if (edits_opt->count() > 0 && request->models_file.empty()) {
      throw CLI::ValidationError("--edits", "edits apply to model maps: give --models MAPS.exr");
    }
    if (request->directions_width % 2 != 0) {
      throw CLI::ValidationError("--directions", "expected an even number");
    }
    request->auto_exposure = exp_opt->count() == 0;
    request->exposure_stops = *exposure;
    const auto outputs = relight_field_file(*request);
    std::string title = request->models_file.empty()
                            ? "relit: " + request->field_file.filename().string()
                            : "models: " + request->models_file.filename().string();
    if (!request->edits_file.empty()) title += " + " + request->edits_file.filename().string();
    write_contact_sheet(request->out_dir / "contact_sheet.png", outputs, title);
  });
}

}  // namespace ls::cli
