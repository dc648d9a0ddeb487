#include "capture/field.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <new>

#include "lightstage/errors.h"
#include "lightstage/memory.h"

namespace ls::capture {

std::vector<FieldLight> lights_along(const std::vector<Eigen::Vector3d>& dirs_in_stage) {
  std::vector<FieldLight> lights;
  lights.reserve(dirs_in_stage.size());
  for (size_t l = 0; l < dirs_in_stage.size(); ++l) lights.push_back({int(l), dirs_in_stage[l]});
  return lights;
}

std::vector<Eigen::Vector3d> light_directions(const std::vector<FieldLight>& lights) {
  std::vector<Eigen::Vector3d> dirs;
  dirs.reserve(lights.size());
  for (const FieldLight& light : lights) dirs.push_back(light.dir_in_stage);
  return dirs;
}

ReflectanceField::ReflectanceField(int width, int height, std::vector<FieldLight> lights)
    : width_(width), height_(height), lights_(std::move(lights)) {
  if (width <= 0 || height <= 0) {
    throw InputError("reflectance field: size must be positive, got " + std::to_string(width) +
                     "x" + std::to_string(height));
  }
  const std::size_t bytes = bytes_for(width, height, num_lights());
  require_memory(bytes,
                 "reflectance field " + std::to_string(width) + "x" + std::to_string(height) +
                     " with " + std::to_string(num_lights()) + " LEDs",
                 "use a smaller crop or fewer LEDs");
  try {
    values_.assign(bytes / sizeof(float), 0.0f);
  } catch (const std::bad_alloc&) {
    throw InputError("reflectance field " + std::to_string(width) + "x" + std::to_string(height) +
                     " with " + std::to_string(num_lights()) + " LEDs: allocating " +
                     std::to_string(bytes >> 20) + " MiB failed; use a smaller crop or fewer LEDs");
  }
}

ReflectanceField ReflectanceField::without_values(int width, int height,
                                                  std::vector<FieldLight> lights) {
  ReflectanceField field;
  field.width_ = width;
  field.height_ = height;
  field.lights_ = std::move(lights);
  return field;
}

ValidLights valid_lights(const ReflectanceField& field) {
  ValidLights out;
  for (int l = 0; l < field.num_lights(); ++l) {
    if (!field.lights()[l].valid) continue;
    out.index.push_back(l);
    out.dirs_in_stage.push_back(field.lights()[l].dir_in_stage.normalized());
  }
  out.near = has_near_lights(field);
  return out;
}

Eigen::Vector3d reference_point(const FieldView& view, int width, int height, int x, int y) {
  // Pixel centres, row 0 at the top (+Y): the simulator's and CameraSpec's convention.
  const double half_h = 0.5 * view.ortho_height_m;
  const double aspect = double(width) / height;
  const double ndc_x = 2.0 * (x + 0.5) / width - 1.0;
  const double ndc_y = 1.0 - 2.0 * (y + 0.5) / height;
  if (view.fov_y_deg <= 0) {
    return {ndc_x * half_h * aspect, ndc_y * half_h, view.reference_z_m};
  }
  const double tan_half = std::tan(0.5 * view.fov_y_deg * std::numbers::pi / 180.0);
  const double depth = view.camera_distance_m - view.reference_z_m;  // Along -Z, metres.
  if (!(depth > 0)) return {0, 0, view.reference_z_m};
  return {ndc_x * tan_half * aspect * depth, ndc_y * tan_half * depth, view.reference_z_m};
}

double near_light_gain(const FieldView& view, int width, int height, int x, int y,
                       const Eigen::Vector3d& position, double reference_m) {
  return (position - reference_point(view, width, height, x, y)).squaredNorm() /
         (reference_m * reference_m);
}

void camera_ray(const FieldView& view, int width, int height, int x, int y, Eigen::Vector3d* origin,
                Eigen::Vector3d* dir) {
  const double aspect = double(width) / height;
  const double ndc_x = 2.0 * (x + 0.5) / width - 1.0;
  const double ndc_y = 1.0 - 2.0 * (y + 0.5) / height;
  if (view.fov_y_deg <= 0) {
    const double half_h = 0.5 * view.ortho_height_m;
    *origin = Eigen::Vector3d(ndc_x * half_h * aspect, ndc_y * half_h, 100.0);
    *dir = Eigen::Vector3d(0, 0, -1);
    return;
  }
  const double tan_half = std::tan(0.5 * view.fov_y_deg * std::numbers::pi / 180.0);
  *origin = Eigen::Vector3d(0, 0, view.camera_distance_m);
  *dir = Eigen::Vector3d(ndc_x * tan_half * aspect, ndc_y * tan_half, -1.0).normalized();
}

bool has_near_lights(const ReflectanceField& field) {
  if (!field.view) return false;
  for (const FieldLight& light : field.lights()) {
    if (light.position_in_stage) return true;
  }
  return false;
}

PixelLightDirs::PixelLightDirs(const ReflectanceField& field, int x, int y) : field_(field) {
  if (field.view) {
    reference_ =
        reference_point(*field.view, field.width(), field.frame_height(), x, field.first_row() + y);
  }
}

Eigen::Vector3d PixelLightDirs::operator()(int light) const {
  const FieldLight& l = field_.lights()[light];
  if (l.position_in_stage && reference_) {
    const Eigen::Vector3d to_led = *l.position_in_stage - *reference_;
    const double distance = to_led.norm();
    if (distance > 1e-9) return to_led / distance;
  }
  return l.dir_in_stage.normalized();
}

float ReflectanceField::largest_value() const {
  float largest = 0;
  for (const float v : values_) largest = std::max(largest, std::isfinite(v) ? v : 0.0f);
  return largest;
}

void ReflectanceField::set_light_image(int light, const std::vector<float>& rgb) {
  for (std::size_t p = 0; p < std::size_t(width_) * height_; ++p) {
    std::copy_n(&rgb[3 * p], 3, values_.data() + p * lights_.size() * 3 + 3 * std::size_t(light));
  }
}

void copy_attributes(const ReflectanceField& from, ReflectanceField& to) {
  to.scene_time_s = from.scene_time_s;
  to.source = from.source;
  to.noise = from.noise;
  to.view = from.view;
}

ReflectanceField select_lights(const ReflectanceField& field,
                               const std::vector<int>& light_indices) {
  std::vector<FieldLight> lights;
  lights.reserve(light_indices.size());
  for (int l : light_indices) lights.push_back(field.lights()[size_t(l)]);
  const bool header = field.values().empty() && field.width() * field.height() > 0;
  ReflectanceField out =
      header ? ReflectanceField::without_values(field.width(), field.height(), lights)
             : ReflectanceField(field.width(), field.height(), lights);
  for (int y = 0; y < field.height() && !header; ++y) {
    for (int x = 0; x < field.width(); ++x) {
      const float* in = field.pixel(x, y);
      float* o = out.pixel(x, y);
      for (size_t i = 0; i < light_indices.size(); ++i) {
        for (int c = 0; c < 3; ++c) o[3 * i + c] = in[3 * light_indices[i] + c];
      }
    }
  }
  copy_attributes(field, out);
  if (field.frame_height() != field.height()) out.set_band(field.first_row(), field.frame_height());
  return out;
}

void shape_band(const ReflectanceField& header, int y0, int y1, ReflectanceField& band) {
  LS_CHECK(0 <= y0 && y0 < y1 && y1 <= header.height(), "rows out of the field");
  if (band.width() != header.width() || band.height() != y1 - y0 ||
      band.num_lights() != header.num_lights()) {
    band = ReflectanceField();
    band = ReflectanceField(header.width(), y1 - y0, header.lights());
  }
  band.lights() = header.lights();
  copy_attributes(header, band);
  band.set_band(y0, header.height());
}

FieldBands bands_of(RowReader read_rows, int height, int rows) {
  return [read_rows = std::move(read_rows), height, rows](const BandVisitor& visit) {
    ReflectanceField band;
    for (int y0 = 0; y0 < height; y0 += rows) {
      read_rows(y0, std::min(height, y0 + rows), band);
      visit(band);
    }
  };
}

}  // namespace ls::capture
