// Where an imported set's lights are when not as its files list them: found from the mirror
// spheres in its images, or given by a calibrated stage (olat_images.h place_olat_lights).
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "capture/olat_images.h"
#include "capture/olat_pixels.h"
#include "capture/sphere_lights.h"
#include "lightstage/errors.h"
#include "lightstage/stage.h"
#include "lightstage/statistics.h"

namespace ls::capture {

namespace {

std::string name_of(const OlatLight& light) {
  return light.image.filename().string() + " (" + light.where + ")";
}

// Each light's new direction (unset: kept) and how far the listed one was from it.
void take_directions(OlatImageSet& set,
                     const std::vector<std::optional<Eigen::Vector3d>>& directions) {
  std::vector<double> errors;
  for (size_t l = 0; l < set.lights.size(); ++l) {
    OlatLight& light = set.lights[l];
    if (!directions[l]) continue;
    errors.push_back(angle_between_deg(light.dir_in_stage, *directions[l]));
    light.dir_in_stage = *directions[l];
  }
  if (errors.empty()) return;
  set.placement.listed_error_max_deg = *std::max_element(errors.begin(), errors.end());
  set.placement.listed_error_median_deg = median(errors);
}

void place_from_spheres(OlatImageSet& set, const OlatImportOptions& options,
                        const ImageHeader& first) {
  const Linearizer linearizer(set.transfer, options.gamma);
  std::vector<std::string> names;
  for (const OlatLight& light : set.lights) names.push_back(light.image.filename().string());
  SphereLightOptions spheres = options.spheres;
  // A highlight an integer file clipped is located by its core (capture/light_calibration.h,
  // HighlightOptions; measured on PSBox's chrome sphere and the simulated dome,
  // sphere_lights_test). Its luminance reaches the ceiling only where every channel clipped.
  if (is_integer_format(first.format)) {
    spheres.highlight.saturation_level = 0.999 * linearizer.ceiling(first.format);
    spheres.highlight.clipped_core_fraction = 0.975;
  }
  const PlacedLights placed = place_lights_from_spheres(
      first.width, first.height, names,
      [&](int l, int y0, int y1) {
        const OlatLight& light = set.lights[size_t(l)];
        return read_linear_rows(light.image, light.where, linearizer, y0, y1);
      },
      spheres, options.progress);
  for (const ImageProblem& p : placed.problems) {
    set.warnings.push_back(
        name_of(set.lights[size_t(p.led_index)]) + ": " +
        (p.sphere >= 0 ? "sphere " + std::to_string(p.sphere + 1) + ": " : std::string()) + p.what);
  }
  for (size_t l = 0; l < set.lights.size(); ++l) {
    if (!placed.directions[l]) {
      set.warnings.push_back(name_of(set.lights[l]) +
                             ": no sphere shows its light: its listed direction is kept");
    }
  }
  take_directions(set, placed.directions);
  set.placement.description = placed.description;
  std::vector<double> distances;
  for (const auto& p : placed.positions) {
    if (p) distances.push_back(p->norm());
  }
  if (distances.empty()) return;  // Directions only.
  // The LEDs taken as equally bright: one distance for every light's falloff. And every light
  // near, or the field would mix units: one without a position stands at the others' median
  // distance along its direction.
  const double median_m = median(distances);
  for (size_t l = 0; l < set.lights.size(); ++l) {
    OlatLight& light = set.lights[l];
    light.position_in_stage = placed.positions[l];
    light.falloff_from_m = median_m;
    if (light.position_in_stage) continue;
    light.position_in_stage = median_m * light.dir_in_stage.normalized();
    set.warnings.push_back(name_of(light) + ": no position: put at the others' median distance");
  }
  set.view = placed.view;
}

void place_from_stage(OlatImageSet& set, const std::filesystem::path& stage_file,
                      const ImageHeader& first) {
  const Stage stage = load_stage(stage_file);
  const std::string where = stage_file.string();
  if (stage.leds.size() != set.lights.size()) {
    throw InputError(where + ": leds: expected one per image of " + set.source.string() + " (" +
                     std::to_string(set.lights.size()) + ", in order), got " +
                     std::to_string(stage.leds.size()));
  }
  const CameraSpec& camera = stage.camera;
  // The view is scale-free in pixels: a set exported smaller than the camera still fits.
  const double aspect = double(first.width) / first.height;
  const double camera_aspect = double(camera.width) / camera.height;
  if (std::abs(aspect / camera_aspect - 1) > 0.01) {
    throw InputError(where + ": camera: expected the images' shape (" +
                     std::to_string(first.width) + "x" + std::to_string(first.height) + "), got " +
                     std::to_string(camera.width) + "x" + std::to_string(camera.height));
  }
  std::vector<std::optional<Eigen::Vector3d>> directions;
  int near = 0;
  for (size_t l = 0; l < set.lights.size(); ++l) {
    const Led& led = stage.leds[l];
    OlatLight& light = set.lights[l];
    directions.emplace_back(led.dir_in_stage.normalized());
    // The stage's calibrated irradiance at the origin, per channel, as a build divides it out.
    light.intensity_rgb = led.irradiance_rgb().cast<float>();
    if (led.distance_m) {
      light.position_in_stage = *led.distance_m * led.dir_in_stage.normalized();
      light.falloff_from_m = *led.distance_m;
      ++near;
    }
  }
  take_directions(set, directions);
  if (near > 0) {
    set.view = FieldView{camera.fov_y_deg, camera.distance_m, camera.ortho_height_m,
                         stage.calibration.reference_z_m};
  }
  char text[160];
  std::snprintf(text, sizeof(text), "%zu LEDs of %s in order, %d with positions, ",
                stage.leds.size(), where.c_str(), near);
  set.placement.description = std::string(text) + "their calibrated irradiance divided out";
}

}  // namespace

void place_olat_lights(OlatImageSet& set, const OlatImportOptions& options,
                       const ImageHeader& first) {
  if (!options.stage_file.empty()) {
    place_from_stage(set, options.stage_file, first);
  } else if (!options.spheres.outlines.empty()) {
    place_from_spheres(set, options, first);
  }
}

}  // namespace ls::capture
