#pragma once
// Importers of existing one-light-at-a-time (OLAT) photo sets into a ReflectanceField, so that
// `fit` and `relight` take real photographs:
//  * RTI sets described by an .lp file: line 1 a count N, then N lines "image x y z";
//  * the DiLiGenT photometric-stereo layout: a folder with filenames.txt, light_directions.txt,
//    light_intensities.txt, mask.png and 16-bit PNGs.
// Field value = linear pixel value / light intensity (per channel), i.e. the pixel's value per unit
// irradiance of that light, up to one global scale (field.h). Lights get ids 0..N-1 in file order.
//
// Direction frames: both formats give unit vectors toward the light in the camera's frame, x right
// and y up in the image, z toward the camera. The stage frame has the camera on +Z looking toward
// -Z with +Y up, so image right is +X: the mapping is the identity.
//
// Saturation: a pixel at the file's maximum code (255 or 65535) is only a lower bound. Integer
// files give each light its ceiling (FieldLight::saturates_at: the maximum code after the transfer
// curve and the intensity), so relight/fit/normals.h and fit.h leave such samples out as censored;
// they are counted and reported (summary). With `zero_saturated` they become 0 instead, which the
// normals and fits treat as shadowed (left out), at the cost of darkening relit highlights.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "capture/sphere_lights.h"
#include "lightstage/progress.h"
#include "lightstage/rank_split.h"

namespace ls::capture {

enum class OlatFormat { kRtiLp, kDiligent };
const char* to_string(OlatFormat format);

// How integer pixel codes map to linear values (float files are always read as linear).
enum class TransferCurve {
  kSrgb,    // IEC 61966-2-1 piecewise curve.
  kGamma,   // linear = code^gamma, code normalised to [0, 1].
  kLinear,  // linear = code (raw sensor data, e.g. DiLiGenT's 16-bit PNGs).
};

struct OlatImportOptions {
  // Empty: the format's default (RTI .lp sets: sRGB, they are usually JPEGs, linear when their
  // images are camera raw files; DiLiGenT: linear).
  std::optional<TransferCurve> transfer;
  double gamma = 2.2;  // For TransferCurve::kGamma; in (0, 10].
  // > 0: downsizes (area averaging) so that max(width, height) <= max_size. 0 keeps the size.
  int max_size = 0;
  // Saturated samples (max code): false keeps them as lower bounds, true writes 0 (see above).
  bool zero_saturated = false;
  // The scene time the field records (ReflectanceField::scene_time_s), seconds: a set's place in
  // a time-lapse, for `lightstage fit --time`. Finite.
  double scene_time_s = 0.0;
  // Phase "import", images read; called from worker threads but never two at a time.
  ProgressFn progress;
  // Imports into a file: how it holds the values (capture/half_storage.h).
  StorageChoice storage = StorageChoice::kFloat;
  // Each image is checked against what the others predict at its light
  // (capture/image_consistency.h): those that disagree (shifted, another light's, black) are
  // listed (summary) and, with leave_out_inconsistent, left out of the field. keep_all: not
  // checked.
  bool keep_all = false;
  bool leave_out_inconsistent = true;
  // Mirror spheres in the frames (capture/sphere_lights.h): the lights' directions (one sphere)
  // or positions (two) from their highlights replace the listed directions. With positions the
  // field holds near lights (field.h: each pixel's own direction, the falloff divided out, the
  // LEDs taken as equally bright), seen by an orthographic or (focal length) pinhole view of the
  // plane z = 0 the spheres rest on.
  SphereLightOptions spheres;
  // Or a calibrated stage file (lightstage/stage.h) whose LEDs are the set's lights in order: their
  // directions, positions and irradiance (per channel) replace what the set lists, and its camera
  // gives the view (the images may be a smaller export of its frames). Not with spheres.
  std::filesystem::path stage_file;

  // Empty when valid; otherwise a sentence naming the option and its valid range.
  std::string validate() const;
};

struct OlatImportSummary {
  OlatFormat format = OlatFormat::kRtiLp;
  std::filesystem::path source;  // The .lp file or the DiLiGenT folder.
  int images = 0;
  int source_width = 0, source_height = 0;  // As stored.
  int width = 0, height = 0;                // Of the field (after --max-size).
  std::string pixel_format;                 // Of the first image, e.g. "8-bit RGB", "16-bit grey".
  std::string transfer_undone;              // "sRGB curve", "gamma 2.2", "none (linear)".
  double min_dir_z = 0, max_dir_z = 0;      // Range of the light directions' z (toward camera).
  long long saturated_samples = 0;          // Pixel channels at the maximum code, all images.
  double saturated_fraction = 0.0;          // Of all samples.
  int masked_out_pixels = 0;                // DiLiGenT: pixels outside mask.png (set to 0).
  bool intensities_divided = false;         // DiLiGenT: light_intensities.txt divided out.
  std::vector<std::string> notes;           // E.g. image paths found by file name only.
  std::vector<std::string> warnings;        // What was assumed: e.g. no light_intensities.txt.
  double seconds = 0.0;
  FieldStorage storage;                 // Into a file: how it holds the values,
  std::optional<HalfCheck> half_check;  // and (half or auto storage) what half would cost.
  int resumed_lights = 0;  // In bands: lights an earlier, killed import had read (kept).
  // The images found inconsistent with the others, each "IMAGE (WHERE): reason", and those left
  // out of the field (their indices in the set; the field's lights are the others, ids kept).
  std::vector<std::string> inconsistent;
  std::vector<int> left_out_lights;
  std::string consistency;  // What the check did, a sentence.
  // With spheres or a stage: how the lights were placed (a sentence), and how far the listed
  // directions were from the placed ones (degrees; median and largest over the lights placed).
  std::string light_placement;
  double listed_direction_error_median_deg = 0, listed_direction_error_max_deg = 0;
  bool inconsistent_left_out() const { return !left_out_lights.empty(); }
  int lights() const { return images - int(left_out_lights.size()); }  // In the field.
};

// Which format `source` is: an .lp file, a folder with exactly one .lp file, or a folder with
// filenames.txt and light_directions.txt (DiLiGenT). InputError naming it otherwise.
OlatFormat detect_olat_format(const std::filesystem::path& source);
// The curve a format's images are undone by when OlatImportOptions::transfer is empty: sRGB for
// RTI sets (usually JPEGs), linear for DiLiGenT (raw 16-bit sensor data).
TransferCurve default_transfer(OlatFormat format);
// "srgb", "gamma", "linear".
const char* to_string(TransferCurve curve);

// `lp_file` may also be a folder holding exactly one .lp file.
ReflectanceField import_rti_lp(const std::filesystem::path& lp_file,
                               const OlatImportOptions& options,
                               OlatImportSummary* summary = nullptr);
ReflectanceField import_diligent(const std::filesystem::path& folder,
                                 const OlatImportOptions& options,
                                 OlatImportSummary* summary = nullptr);
// Detects the format and imports.
ReflectanceField import_olat(const std::filesystem::path& source, const OlatImportOptions& options,
                             OlatImportSummary* summary = nullptr);

// The field `source` imports into, without its values (size, lights): cheap, only the first
// image's header is read. InputErrors as import_olat's for the set's description.
ReflectanceField olat_header(const std::filesystem::path& source, const OlatImportOptions& options);
// The bytes on disk of the images `source` lists: what the user holds of the set.
std::uintmax_t olat_image_bytes(const std::filesystem::path& source);

// An OLAT set read in bands of rows straight from its images, every light's rows of a band at
// once: the values import_olat gives, with neither the field in memory nor a copy on disk (a set
// larger than memory). Every image stays open and its decoder reads on from where the
// last band ended; a band above the last one read opens the images again (a new pass).
class OlatBands {
 public:
  // Null when the set cannot be read so: imported at another size (options.max_size), or more
  // images than may be open at once (kMaxOpenImages). InputErrors as import_olat's.
  static std::unique_ptr<OlatBands> open(const std::filesystem::path& source,
                                         const OlatImportOptions& options);
  static constexpr int kMaxOpenImages = 512;
  ~OlatBands();
  OlatBands(const OlatBands&) = delete;
  OlatBands& operator=(const OlatBands&) = delete;

  int width() const { return header_.width(); }
  int height() const { return header_.height(); }
  // The field's lights (with the images' saturation ceilings) and attributes, no values.
  const ReflectanceField& header() const { return header_; }
  // The rows of a band that, with the decoding buffers, fits in `bytes` (at least one).
  int rows_within(std::size_t bytes) const;
  // Rows [y0, y1) into band (reallocated only when its size changes). InputError naming the .lp
  // line and the image when one cannot be decoded there.
  void read_rows(int y0, int y1, ReflectanceField& band);

  struct Images;  // The open images (olat_bands.cc).
  OlatBands(std::unique_ptr<Images> images, ReflectanceField header);

 private:
  std::unique_ptr<Images> images_;
  ReflectanceField header_;
};

// A light's image as imported (width * height * 3 floats, field units) and its direction.
using LightImageFn = std::function<void(int light, const Eigen::Vector3d& dir_in_stage,
                                        const std::vector<float>& rgb)>;
// Detects the format and imports into the field file `out` (write_field's format), holding no
// more of the field than `memory` at once: bands through a spill file beside `out` when the field
// is larger (capture/band_spill.h), the same bytes either way. on_light (optional) sees each
// light's image as it is read. In bands a killed import resumes, and under MPI the lights are split
// over the ranks (capture/olat_images.h: import_images_to_file). Returns the rows per band (the
// height: imported in memory).
int import_olat_to_file(const std::filesystem::path& source, const OlatImportOptions& options,
                        const std::filesystem::path& out, const ExrAttributes& attributes,
                        const MemoryBudget& memory, const LightImageFn& on_light = {},
                        OlatImportSummary* summary = nullptr, const RankSplit& split = {});

}  // namespace ls::capture
