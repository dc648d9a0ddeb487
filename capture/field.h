#pragma once
// The reflectance field R(x, l): pixel x's linear value under LED l, per unit of that LED's
// calibrated irradiance at the origin, after dark subtraction and HDR merge (DESIGN.md). It already
// contains f_r(x, w_l, w_o) * cos(theta_l) and any shadowing; relighting is I(x) = sum_l R(x, l) *
// E_l.
// Near LEDs (FieldLight::position_in_stage set): R(x, l) is per unit of the LED's irradiance at the
// pixel's reference point X(x) (FieldView: where the pixel's camera ray meets the plane z =
// reference_z_m), i.e. the build multiplied by (|P - X| / |P|)^2, and the light arrives along
// PixelLightDirs = (P - X) / |P - X| rather than along dir_in_stage. A flat field, when the stage
// has one, is divided out too: R is per unit of the LED's irradiance as calibrated at that pixel.
//
// Layout: pixel-major, values[((y * width + x) * num_lights + l) * 3 + c], float32.
// Why: relighting streams every pixel's 3L values exactly once, contiguously, against a small E
// vector that stays in L1, and writes each output pixel once; per-pixel fitting reads one pixel's
// samples contiguously. Rows are independent, so both parallelise over row tiles.
#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "lightstage/image.h"

namespace ls::capture {

struct FieldLight {
  int led_id = 0;
  Eigen::Vector3d dir_in_stage{0, 1, 0};
  bool valid = true;  // False for an LED found dead or missing: its samples are zero, not data.
  // Saturation ceiling per channel (RGB), in field units: the value a sample takes when the sensor
  // clipped it in every exposure (the HDR merge then keeps a lower bound). Samples at or above
  // kCensoredFraction * saturates_at are censored: the truth is at least that, not that.
  // +infinity: never saturates (simulated, or unknown for older files).
  Eigen::Vector3f saturates_at = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
  // Near LED: its position in metres (stage frame); unset for a distant LED.
  std::optional<Eigen::Vector3d> position_in_stage;
};

// Valid distant lights along `dirs_in_stage`, led_id their index: a dome known by directions only.
std::vector<FieldLight> lights_along(const std::vector<Eigen::Vector3d>& dirs_in_stage);
// The dir_in_stage of every light, valid or not, in order.
std::vector<Eigen::Vector3d> light_directions(const std::vector<FieldLight>& lights);

// Where a field's pixels lie in the stage: the camera's geometry (CameraSpec's, lightstage/
// stage.h: on +Z looking toward -Z, square pixels, row 0 at the top) and the reference surface, the
// plane z = reference_z_m that stands in for the unknown surface when near LEDs need a distance.
struct FieldView {
  double fov_y_deg = 0.0;        // 0: orthographic.
  double camera_distance_m = 4;  // Pinhole: centre at (0, 0, camera_distance_m).
  double ortho_height_m = 2.4;   // Orthographic: height of the view.
  double reference_z_m = 0.0;
};

// A channel value at or above this fraction of its light's saturates_at is censored (a lower
// bound). Below 1 so that a clipped sample whose dark level was a little above the mean still
// counts.
inline constexpr float kCensoredFraction = 0.999f;
// Whether any channel of a light's sample (3 values, RGB) is censored by saturation.
inline bool is_saturated(const FieldLight& light, const float* rgb) {
  for (int c = 0; c < 3; ++c) {
    if (rgb[c] >= kCensoredFraction * light.saturates_at[c]) return true;
  }
  return false;
}

// Measurement noise of a field's values, in field units (value per unit LED irradiance):
// variance(v) = read_variance + shot_variance_per_unit * max(v, 0). Estimated from the capture
// when the field is built (how: `method`); `measured` false means nobody estimated it.
struct FieldNoise {
  double read_variance = 0.0;
  double shot_variance_per_unit = 0.0;
  bool measured = false;
  std::string method;  // E.g. "dark-frame pairs + bracket pairs"; empty when not measured.
};

class ReflectanceField {
 public:
  ReflectanceField() = default;
  // Allocates after checking that it fits in available memory (InputError otherwise).
  ReflectanceField(int width, int height, std::vector<FieldLight> lights);
  // Its size, lights and attributes without the values (FieldStream::header): no pixel().
  static ReflectanceField without_values(int width, int height, std::vector<FieldLight> lights);

  int width() const { return width_; }
  int height() const { return height_; }
  int num_lights() const { return int(lights_.size()); }
  const std::vector<FieldLight>& lights() const { return lights_; }
  std::vector<FieldLight>& lights() { return lights_; }

  // The 3 * num_lights() values of one pixel: light-major, RGB innermost.
  const float* pixel(int x, int y) const { return values_.data() + offset(x, y); }
  float* pixel(int x, int y) { return values_.data() + offset(x, y); }
  float at(int x, int y, int light, int c) const { return pixel(x, y)[light * 3 + c]; }
  // Light `light`'s values at every pixel from its image (width * height * 3, row-major, RGB
  // innermost): what a build or an import has of one light at a time.
  void set_light_image(int light, const std::vector<float>& rgb);
  float& at(int x, int y, int light, int c) { return pixel(x, y)[light * 3 + c]; }

  // A band of rows of a larger field (FieldStream::read_rows): its first row there and that
  // field's height, for what depends on where a pixel is in the frame (near-LED directions).
  int first_row() const { return first_row_; }
  int frame_height() const { return frame_height_ > 0 ? frame_height_ : height_; }
  void set_band(int first_row, int frame_height) {
    first_row_ = first_row;
    frame_height_ = frame_height;
  }

  const std::vector<float>& values() const { return values_; }
  // The largest finite value (0 when there is none): what a display-referred export makes white.
  float largest_value() const;
  std::size_t bytes() const { return values_.size() * sizeof(float); }
  static std::size_t bytes_for(int width, int height, int num_lights) {
    return std::size_t(width) * height * num_lights * 3 * sizeof(float);
  }

  // Scene time of this field's capture (time-varying sessions have one field per time step).
  double scene_time_s = 0.0;
  std::string source;  // Session or file it came from, for messages.
  FieldNoise noise;    // Stored in the "lightstage:noise" attribute.
  // Stored in the "lightstage:view" attribute; unset (older files, imports): near LEDs are treated
  // as distant, along dir_in_stage.
  std::optional<FieldView> view;

 private:
  std::size_t offset(int x, int y) const {
    return (std::size_t(y) * width_ + x) * lights_.size() * 3;
  }
  int width_ = 0;
  int height_ = 0;
  int first_row_ = 0;
  int frame_height_ = 0;  // 0: the field is the whole frame.
  std::vector<FieldLight> lights_;
  std::vector<float> values_;
};

// What a field carries beside its values and lights (scene time, source, noise, view).
void copy_attributes(const ReflectanceField& from, ReflectanceField& to);
// A field (or a band of one, or a header without values) with only the given lights (indices
// into field.lights()), values and attributes copied.
ReflectanceField select_lights(const ReflectanceField& field,
                               const std::vector<int>& light_indices);
// `band` made ready to hold rows [y0, y1) of the field `header` describes (its lights and
// attributes, its place in the frame), for a reader to fill; reallocated only when its size
// changes, and then freed first (the last, shorter band must not hold two).
void shape_band(const ReflectanceField& header, int y0, int y1, ReflectanceField& band);

// The lights of a field that hold data (valid), as indices into lights() and unit directions.
struct ValidLights {
  std::vector<int> index;
  std::vector<Eigen::Vector3d> dirs_in_stage;  // Unit.
  bool near = false;  // has_near_lights: each pixel sees them along its own directions.
};
ValidLights valid_lights(const ReflectanceField& field);

// The reference point of pixel (x, y) (its centre) in the stage frame, metres: where its camera ray
// meets the plane z = view.reference_z_m. A pinhole camera at or behind the plane sees it nowhere:
// the point straight below the camera is returned.
Eigen::Vector3d reference_point(const FieldView& view, int width, int height, int x, int y);
// What a value of pixel (x, y) lit by a near LED at `position` (metres) is multiplied by to read
// per unit of the irradiance the LED gives at distance reference_m: (|P - X| / reference_m)^2, X
// the pixel's reference point.
double near_light_gain(const FieldView& view, int width, int height, int x, int y,
                       const Eigen::Vector3d& position, double reference_m);
// The camera ray through pixel (x, y)'s centre: origin and unit direction (toward -Z); an
// orthographic camera's rays start at z = 100, in front of anything on the stage.
void camera_ray(const FieldView& view, int width, int height, int x, int y, Eigen::Vector3d* origin,
                Eigen::Vector3d* dir);
// Whether any light of the field has a position and the field knows its view (per-pixel lights).
bool has_near_lights(const ReflectanceField& field);
// Unit directions toward the lights seen from pixel (x, y) of a field (of a band: its row
// first_row() + y of the frame), the pixel's reference point computed once: toward light `light`
// (index into lights()) from that point for near lights (when the field has a view), otherwise
// along the light's dir_in_stage.
class PixelLightDirs {
 public:
  PixelLightDirs(const ReflectanceField& field, int x, int y);
  Eigen::Vector3d operator()(int light) const;

 private:
  const ReflectanceField& field_;
  std::optional<Eigen::Vector3d> reference_;  // Set when the field has a view.
};

// A field visited band by band, top to bottom (a field larger than memory): a
// FieldBands calls its visitor with each band in turn (a ReflectanceField of the band's rows that
// knows its first_row() and frame_height()). whole_field visits one band, the field itself.
using BandVisitor = std::function<void(const ReflectanceField& band)>;
using FieldBands = std::function<void(const BandVisitor& visit)>;
inline FieldBands whole_field(const ReflectanceField& field) {
  return [&field](const BandVisitor& visit) { visit(field); };
}
// Rows [y0, y1) of a field into `band` (as FieldStream::read_rows).
using RowReader = std::function<void(int y0, int y1, ReflectanceField& band)>;
// Every band of `rows` rows of a field `height` rows high, read in turn into one band.
FieldBands bands_of(RowReader read_rows, int height, int rows);

}  // namespace ls::capture
