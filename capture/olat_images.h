#pragma once
// The pixel half of the OLAT importers (capture/olat_import.h): a list of images, each with its
// light's direction and intensity, read as linear RGB into a ReflectanceField. The text formats
// that produce the list (.lp files, DiLiGenT folders) are parsed in olat_import.cc.
#include <Eigen/Core>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "capture/olat_import.h"
#include "capture/olat_pixels.h"
#include "lightstage/rank_split.h"

namespace ls::capture {

// One light of an OLAT set, as its files describe it.
struct OlatLight {
  std::filesystem::path image;
  Eigen::Vector3d dir_in_stage{0, 0, 1};
  Eigen::Vector3f intensity_rgb{1, 1, 1};  // Divided out of the pixel values.
  std::string where;                       // "FILE:LINE" of the line that names the image.
  // Set when the light is near (placed from spheres or a stage): metres, stage frame; its values
  // are then multiplied by (|P - X| / falloff_from_m)^2 (field.h near_light_gain).
  std::optional<Eigen::Vector3d> position_in_stage;
  double falloff_from_m = 1.0;
};

// Where the lights came from when not as listed (olat_lights.cc).
struct LightPlacement {
  std::string description;  // A sentence; empty: as listed.
  // How far the listed directions were from the placed ones, degrees.
  double listed_error_median_deg = 0, listed_error_max_deg = 0;
};

struct OlatImageSet {
  OlatFormat format = OlatFormat::kRtiLp;
  std::filesystem::path source;
  std::vector<OlatLight> lights;
  TransferCurve transfer = TransferCurve::kSrgb;
  std::vector<float> mask;  // Empty, or 1/0 per pixel at the images' size (1 = object).
  int mask_width = 0, mask_height = 0;
  std::string mask_name;
  std::vector<std::string> notes;
  std::vector<std::string> warnings;  // What was assumed for what the set does not say.
  // Near lights: the view of the source images.
  std::optional<FieldView> view;
  LightPlacement placement;
};

// The field's size and lights without its values: only the first image's header is read.
ReflectanceField images_header(OlatImageSet set, const OlatImportOptions& options);

// Reads every image (in parallel), undoes the transfer curve, applies the mask, downsizes to
// options.max_size and divides by each light's intensity. All images must share the first one's
// size. Integer files give each light its saturation ceiling (FieldLight::saturates_at).
ReflectanceField import_images(OlatImageSet set, const OlatImportOptions& options,
                               OlatImportSummary* summary);

// The same into the field file `out` (write_field's format), holding no more of the field than
// `memory` at once (capture/band_spill.h: bands through a spill file beside `out` when the
// field is larger; the same bytes either way). on_light (optional) sees each light's image.
// In bands, the spill and a record per light are kept in OUT.partial/ until the field is written
// (a killed import resumes from the lights it read; identity: the source and `attributes`), and
// under MPI (`split`) each rank reads its share of the lights, rank 0 takes the others' from their
// records and writes the field (the others return once theirs are in).
// Returns the rows per band (the height: imported in memory).
int import_images_to_file(OlatImageSet set, const OlatImportOptions& options,
                          const std::filesystem::path& out, const ExrAttributes& attributes,
                          const MemoryBudget& memory, const LightImageFn& on_light,
                          OlatImportSummary* summary, const RankSplit& split = {});

// The lights placed as options say, before the images are read (olat_lights.cc): from the mirror
// spheres in the images (options.spheres: their directions, or positions and the view) or from a
// stage file (options.stage_file: its LEDs in order, their calibrated irradiance and positions,
// its camera's view). `first`: the first image's header. InputError naming the stage file when it
// does not fit the set.
void place_olat_lights(OlatImageSet& set, const OlatImportOptions& options,
                       const ImageHeader& first);

// OlatBands::open's work once the set is read (olat_bands.cc).
std::unique_ptr<OlatBands> open_olat_bands(OlatImageSet set, const OlatImportOptions& options);

// Reads a mask image into set.mask (non-zero in any of the first three channels = object).
void read_mask(const std::filesystem::path& mask_file, OlatImageSet& set);

}  // namespace ls::capture
