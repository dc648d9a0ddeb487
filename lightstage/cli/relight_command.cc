// lightstage relight: field + environment maps -> relit images (EXR + PNG previews + sheet).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <set>

#include "capture/field.h"
#include "lightstage/cli/commands.h"
#include "lightstage/errors.h"
#include "lightstage/progress.h"
#include "relight/envmap.h"
#include "relight/light_cells.h"
#include "relight/relight.h"

namespace ls::cli {

namespace fs = std::filesystem;

std::vector<RelitOutput> relight_field_file(const RelightRequest& request) {
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

      std::string name = map_path.stem().string();
      if (used_names.count(name)) name = map_path.parent_path().filename().string() + "_" + name;
      if (request.rotations_deg.size() > 1 || rotation != 0.0) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "_rot%03d", int(std::lround(rotation)));
        name += buf;
      }
      used_names.insert(name);
      relit.channel_names = {"R", "G", "B"};
      write_exr(request.out_dir / (name + ".exr"), relit);
      const double stops =
          request.auto_exposure ? auto_exposure_stops(relit) : request.exposure_stops;
      const fs::path png = request.out_dir / (name + ".png");
      write_png_preview(png, relit, stops);
      outputs.push_back({png, name});
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
      "stands for its spherical Voronoi cell of directions, I = sum_l R_l E_l. Writes NAME.exr "
      "(linear) and NAME.png (tone-mapped preview) per map and rotation, and contact_sheet.png.");
  cmd->add_option("field", request->field_file, "Reflectance field (.exr from 'lightstage build').")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--env", request->maps, "Environment map(s), lat-long .exr or .hdr.")
      ->required()
      ->check(CLI::ExistingFile);
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
  cmd->callback([request, exposure, exp_opt] {
    request->auto_exposure = exp_opt->count() == 0;
    request->exposure_stops = *exposure;
    const auto outputs = relight_field_file(*request);
    write_contact_sheet(request->out_dir / "contact_sheet.png", outputs,
                        "relit: " + request->field_file.filename().string());
  });
}

}  // namespace ls::cli
