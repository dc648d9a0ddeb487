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
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/exr_band_reader.h"
#include "capture/half_storage.h"
#include "lightstage/image.h"
#include "lightstage/memory.h"

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

// OpenEXR, float, one channel per LED and colour named "led042.R" etc., pixel-interleaved (which
// is exactly the in-memory layout); LED directions, validity, (where finite) saturation ceilings
// and (near LEDs) positions in the "lightstage:lights" attribute ({id, dir, valid, saturates_at:
// [r, g, b], position: [x, y, z]}; saturates_at and position are optional on read, absent = never
// saturates, distant); the view in "lightstage:view" (optional); `attributes` as given (e.g. the
// options the field was built with).
// tile_size > 0: a tiled EXR of tile_size^2 tiles, each holding every LED of its pixels, so a
// region is read without the rest of its rows; 0: scanlines.
// storage: half values (capture/half_storage.h) or float, recorded in "lightstage:storage".
void write_field(const std::filesystem::path& path, const ReflectanceField& field,
                 const ExrAttributes& attributes = {}, int tile_size = 0,
                 FieldStorage storage = {});
// The storage a choice gives this field: half where asked, or (auto) where check_half passes;
// float otherwise. *check, when given: the check (half or auto; untouched for float).
FieldStorage choose_storage(const ReflectanceField& field, StorageChoice choice,
                            HalfCheck* check = nullptr);
ReflectanceField read_field(const std::filesystem::path& path);

// A field file written band by band, top to bottom (a field built or imported without holding it):
// the header (lights, noise, view, time) from `header` (its values unused), the file as
// write_field's. Written under a temporary name; finish() renames it into place once every row is
// written, and a writer destroyed before that removes it: no partial field is ever left.
class FieldWriter {
 public:
  FieldWriter(const std::filesystem::path& path, const ReflectanceField& header,
              const ExrAttributes& attributes = {}, int tile_size = 0, FieldStorage storage = {});
  ~FieldWriter();
  FieldWriter(const FieldWriter&) = delete;
  FieldWriter& operator=(const FieldWriter&) = delete;
  // Rows [y0, y0 + band.height()): the next rows, whole tile rows where tiled.
  void write_rows(int y0, const ReflectanceField& band);
  void finish();

 private:
  struct File;
  std::unique_ptr<File> file_;
  int width_, height_, next_row_ = 0;
};

// A field visited band by band, top to bottom (a field larger than memory): a
// FieldBands calls its visitor with each band in turn (a ReflectanceField of the band's rows that
// knows its first_row() and frame_height()). whole_field visits one band, the field itself.
using BandVisitor = std::function<void(const ReflectanceField& band)>;
using FieldBands = std::function<void(const BandVisitor& visit)>;
inline FieldBands whole_field(const ReflectanceField& field) {
  return [&field](const BandVisitor& visit) { visit(field); };
}

// A field on disk read in bands of rows, every LED of a band's pixels at once, so that a field
// larger than memory can be streamed; scanline or tiled files alike. A band is a
// ReflectanceField of the band's rows (its lights, noise and time the file's); it knows nothing
// of its place in the image, so per-pixel light directions (near LEDs) need y offset by the band's
// first row. Errors as read_field's.
class FieldStream {
 public:
  explicit FieldStream(const std::filesystem::path& path);
  ~FieldStream();
  FieldStream(const FieldStream&) = delete;
  FieldStream& operator=(const FieldStream&) = delete;

  int width() const { return header_.width(); }
  int height() const { return header_.height(); }
  // The file's lights, noise, time and view, with no pixels.
  const ReflectanceField& header() const { return header_; }
  // How the file holds its values (read back as floats either way).
  const FieldStorage& storage() const { return storage_; }
  // The rows of a band that fits in `bytes` (reading adds a buffer of about 8 MiB), at least one
  // tile row (tiled files) or one row, whole tiles where the file is tiled.
  int rows_within(std::size_t bytes) const;
  // Bands start on multiples of this (the file's tile height; 1 for scanline files).
  int row_alignment() const;
  // The rows of a band for a memory budget: rows_within(budget.bytes()).
  int band_rows(const MemoryBudget& budget) const;
  // Rows [y0, y1) into band (reallocated only when its size changes).
  void read_rows(int y0, int y1, ReflectanceField& band);
  // Rows [y0, y1) into dst: (y1 - y0) * width() pixels in the field's layout.
  void read_rows_into(int y0, int y1, float* dst);
  // Rows [y0, y1) as the file holds them, in pieces of about 8 MiB (capture/exr_band_reader.h),
  // for a consumer that sums over each pixel's values (relighting): no band is held at all.
  void read_rows_planar(int y0, int y1, const PlanarVisitor& visit);
  // The file in bands of `rows` rows (one band held at a time), each read when visited.
  FieldBands bands(int rows);

 private:
  struct File;
  std::unique_ptr<File> file_;
  ReflectanceField header_;
  FieldStorage storage_;
};

}  // namespace ls::capture
