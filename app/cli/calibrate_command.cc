// lightstage calibrate: LED directions (mirror spheres) and intensities (white target) from
// photographs, written into a calibrated stage file (the work: app/jobs/calibrate_job.h).
//   lightstage calibrate directions --stage S.json --images DIR --out CAL.json
//   lightstage calibrate intensities --stage CAL.json --white DIR --out CAL2.json
//   lightstage calibrate camera --images DIR --board 9x6 --square 30 [--stage S --out CAL.json]
#include <CLI/CLI.hpp>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <memory>

#include "app/cli/commands.h"
#include "app/cli/validators.h"
#include "app/jobs/calibrate_job.h"

namespace ls::cli {
namespace {

void print_problems(const std::vector<capture::ImageProblem>& problems) {
  if (problems.empty()) return;
  std::printf("\n%zu problem(s); those images were left out, the LEDs keep their old values:\n",
              problems.size());
  for (const auto& p : problems) {
    if (p.sphere >= 0) {
      std::printf("  %s: sphere %d: %s\n", p.image.c_str(), p.sphere, p.what.c_str());
    } else {
      std::printf("  %s: %s\n", p.image.c_str(), p.what.c_str());
    }
  }
}

int print_directions(const jobs::CalibrateDirectionsOptions& options, bool quiet) {
  const auto lock = lock_output(options.out);
  const jobs::CalibrateDirectionsSummary job =
      jobs::calibrate_directions(options, progress_printer(quiet));
  for (size_t s = 0; s < job.found_outlines.size(); ++s) {
    const capture::SphereOutline& o = job.found_outlines[s];
    std::printf("sphere %zu: centre (%.2f, %.2f) px, radius %.2f px\n", s, o.center_px.x(),
                o.center_px.y(), o.radius_px);
  }
  std::printf("%6s %10s %12s %s\n", "LED", "moved deg", "distance m", "status");
  for (const auto& e : job.calibration.leds) {
    const Led& before = job.nominal.leds[e.led_index];
    if (!e.ok) {
      std::printf("%6d %10s %12s %s\n", before.id, "-", "-", "kept (see problems)");
      continue;
    }
    char distance[32] = "-";
    if (e.position_in_stage)
      std::snprintf(distance, sizeof distance, "%.4f", e.position_in_stage->norm());
    std::printf("%6d %10.3f %12s %s\n", before.id,
                capture::angle_between_deg(before.dir_in_stage, e.dir_in_stage), distance,
                e.rays.size() > 1 ? "calibrated" : "calibrated (one sphere)");
  }
  print_problems(job.calibration.problems);
  if (!job.written) {
    std::printf("\nno LED direction calibrated: %s not written\n", options.out.c_str());
    return kExitInputError;
  }
  std::printf("\n%d of %zu LED directions calibrated -> %s\n", job.update.directions_changed,
              job.nominal.leds.size(), options.out.c_str());
  return 0;
}

int print_intensities(const jobs::CalibrateIntensitiesOptions& options, bool quiet) {
  const auto lock = lock_output(options.out);
  const jobs::CalibrateIntensitiesSummary job =
      jobs::calibrate_intensities(options, progress_printer(quiet));
  std::printf("%6s %12s %10s %20s %10s\n", "LED", "intensity", "change %", "colour (R G B)",
              "flat rms%");
  for (const auto& e : job.calibration.leds) {
    const Led& before = job.nominal.leds[e.led_index];
    if (!e.ok) {
      std::printf("%6d %12s %10s %20s %10s\n", before.id, "-", "-", "kept (see problems)", "-");
      continue;
    }
    const Led& after = job.calibrated.leds[e.led_index];
    std::printf("%6d %12.5f %+10.2f %6.3f %6.3f %6.3f %10.3f\n", before.id, after.intensity,
                100.0 * (after.intensity / before.intensity - 1.0), after.color_gain[0],
                after.color_gain[1], after.color_gain[2], 100.0 * e.fit_rms);
  }
  print_problems(job.calibration.problems);
  if (!job.written) {
    std::printf("\nno LED intensity calibrated: %s and %s not written\n", options.out.c_str(),
                job.flat_field.c_str());
    return kExitInputError;
  }
  std::printf("\n%d of %zu LED intensities calibrated -> %s (flat fields: %s)\n",
              job.update.intensities_changed, job.nominal.leds.size(), options.out.c_str(),
              job.flat_field.c_str());
  return 0;
}

int print_camera(const jobs::CalibrateCameraOptions& options, bool quiet) {
  std::unique_ptr<OutputLock> lock;
  if (!options.out.empty()) lock = lock_output(options.out);
  const jobs::CalibrateCameraSummary job = jobs::calibrate_camera(options, progress_printer(quiet));
  const capture::CameraCalibration& cal = job.calibration;
  for (const auto& v : cal.views) {
    if (v.found) {
      std::printf("%-32s board found, reprojection RMS %.3f px\n", v.image.c_str(),
                  v.rms_reprojection_px);
    } else {
      std::printf("%-32s no %s board found: left out\n", v.image.c_str(), options.board.c_str());
    }
  }
  if (!cal.ok) {
    std::fprintf(stderr, "calibrate camera: %s\n", cal.problem.c_str());
    return kExitInputError;
  }
  std::printf(
      "\n%dx%d: fx %.3f fy %.3f px, principal point (%.3f, %.3f) px (pixel centres at +0.5), "
      "fov_y %.4f deg\n",
      cal.width, cal.height, cal.fx, cal.fy, cal.cx, cal.cy, cal.fov_y_deg());
  std::printf("distortion (k1 k2 p1 p2 k3):");
  for (double d : cal.distortion) std::printf(" %.6f", d);
  std::printf("\nreprojection RMS %.4f px\n", cal.rms_reprojection_px);
  if (job.written) {
    std::printf("fov_y_deg %.4f -> %s (principal point and distortion not stored)\n",
                cal.fov_y_deg(), options.out.c_str());
  }
  return 0;
}

// A subcommand's exit code, other than 0, as CLI11 passes it on.
void exit_with(int code) {
  if (code != 0) throw CLI::RuntimeError(code);
}

void add_directions_command(CLI::App* cmd) {
  auto options = std::make_shared<jobs::CalibrateDirectionsOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto* sub = cmd->add_subcommand(
      "directions",
      "Mirror spheres: one photograph per LED in --images (ledNNN.* or in stage order) and a "
      "reference shot (reference.*, the spheres brighter than the background) or --circle.");
  sub->add_option("--stage", options->stage_file, "Stage file (its camera took the photographs).")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--images", options->images_dir, "Directory of photographs.")->required();
  sub->add_option("--reference", options->reference, "Reference shot for the sphere outlines.");
  sub->add_option("--circle", options->circles,
                  "Sphere outline(s) instead: cx,cy,r in pixels (x right, y down, pixel "
                  "centres at +0.5); repeat per sphere.")
      ->delimiter(',');
  sub->add_option("--spheres", options->spheres, "Spheres to look for in the reference shot.")
      ->capture_default_str();
  sub->add_option("--sphere-radius", options->sphere_radius_m,
                  "Sphere radius in metres (needed with a perspective camera).")
      ->check(kFinite);
  sub->add_option("--sphere-z", options->sphere_z_m,
                  "Sphere centres' z in metres (orthographic camera).")
      ->capture_default_str()
      ->check(kFinite);
  sub->add_option("--blob-fraction", options->blob_fraction,
                  "Highlight pixels: above this fraction of the peak (0.975 for 8-bit JPEGs).")
      ->capture_default_str()
      ->check(kFinite);
  sub->add_option("--saturation", options->saturation, "Clipped value of the images (0: none).")
      ->check(kFinite);
  sub->add_option("--out", options->out, "Calibrated stage file to write.")->required();
  add_quiet_flag(*sub, *quiet);
  sub->callback([options, quiet] { exit_with(print_directions(*options, *quiet)); });
}

void add_intensities_command(CLI::App* cmd) {
  auto options = std::make_shared<jobs::CalibrateIntensitiesOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto* sub = cmd->add_subcommand(
      "intensities",
      "White target: one photograph per LED in --white of a matte plane facing the camera. LED "
      "directions come from --stage (calibrate directions first).");
  sub->add_option("--stage", options->stage_file, "Stage file, directions already calibrated.")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--white", options->white_dir, "Directory of photographs.")->required();
  sub->add_option("--albedo", options->albedo,
                  "Reflectance of the target (1: intensities relative to it).")
      ->capture_default_str()
      ->check(kFinite);
  sub->add_option("--plane-z", options->plane_z_m, "The plane's z in metres.")
      ->capture_default_str()
      ->check(kFinite);
  sub->add_option("--saturation", options->saturation, "Clipped value of the images (0: none).")
      ->check(kFinite);
  sub->add_option("--flat-field", options->flat_field,
                  "Where to write the flat fields (default: OUT with .flatfield.exr).");
  sub->add_option("--out", options->out, "Calibrated stage file to write.")->required();
  add_quiet_flag(*sub, *quiet);
  sub->callback([options, quiet] { exit_with(print_intensities(*options, *quiet)); });
}

void add_camera_command(CLI::App* cmd) {
  auto options = std::make_shared<jobs::CalibrateCameraOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto* sub = cmd->add_subcommand(
      "camera",
      "Camera intrinsics from photographs of a chessboard in --images (several poses, tilted): "
      "focal lengths, principal point, distortion. With --stage and --out, writes the stage "
      "with the fitted fov_y_deg.");
  sub->add_option("--images", options->images_dir, "Directory of chessboard photographs.")
      ->required();
  sub->add_option("--board", options->board, "Inner corners, WxH (W != H).")->capture_default_str();
  sub->add_option("--square", options->square_mm, "Square size in millimetres.")
      ->capture_default_str()
      ->check(kFinite);
  sub->add_flag("--square-pixels", options->square_pixels, "Fit one focal length (fx = fy).");
  sub->add_option("--stage", options->stage_file, "Stage file to update (with --out).")
      ->check(CLI::ExistingFile);
  sub->add_option("--out", options->out, "Stage file to write with the fitted field of view.");
  add_quiet_flag(*sub, *quiet);
  sub->callback([options, quiet] { exit_with(print_camera(*options, *quiet)); });
}

}  // namespace

void add_calibrate_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "calibrate",
      "Calibrate the dome from photographs: LED directions (and positions, with two spheres) from "
      "mirror spheres, LED intensities, colours and flat fields from a matte white target. Writes "
      "a calibrated stage file; images with problems are listed and left out.");
  cmd->require_subcommand(1);
  add_directions_command(cmd);
  add_intensities_command(cmd);
  add_camera_command(cmd);
}

}  // namespace ls::cli
