#pragma once
// Session -> reflectance field: dark subtraction, HDR merge of each LED's bracket, conversion to
// radiance (camera.radiometric_scale) and division by each LED's calibrated irradiance per channel.
// With the stage's calibration (lightstage/stage.h StageCalibration):
//  * a flat field side car: each LED's values are divided by its flat field at the pixel (bilinear
//    from the side car's grid), so R is per unit of the irradiance the LED really gives there;
//  * near LEDs (Led::distance_m): each value is multiplied by (|P - X| / |P|)^2, X the pixel's
//    reference point (capture/field.h), and the field stores the LEDs' positions and the view.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "capture/hdr_merge.h"
#include "capture/noise_estimate.h"
#include "lightstage/progress.h"
#include "lightstage/rank_split.h"
#include "lightstage/session.h"

namespace ls::capture {

struct BuildOptions {
  int time_step = 0;
  MergeOptions merge;
  // Divide each LED's image by the dome's output drift while it was shot, measured on the plan's
  // reference LED (capture/reference_drift.h). Drift beyond 0.5% is reported either way.
  bool correct_drift = false;
  // Phases "build" (LEDs merged) and, for build_field_file, "write" (bands written).
  ProgressFn progress;
  // build_field_file: the most memory the field's values take at once (bands of rows), and the
  // build_field: what the LEDs merged in flight may take.
  MemoryBudget memory;
  // build_field_file: how the file holds the values (capture/half_storage.h).
  StorageChoice storage = StorageChoice::kFloat;
  // build_field_file under MPI: this process merges its share of the LEDs (RankSplit::mine)
  // into the spill kept beside the field, waits at the barrier for the others, and rank 0 (taking
  // theirs from their records, as a resumed build does) writes the field; the others return once
  // their LEDs are in. In bands whenever split.
  RankSplit split;
};

struct BuildSummary {
  int lights_used = 0;
  std::vector<int> lights_missing;  // LED indices without complete frames, or flagged dead.
  double saturated_fraction = 0.0;  // Samples saturated in every exposure (lower bounds).
  std::string response_used;        // "linear", "gamma 2.2", "table FILE", "recovered".
  double seconds = 0.0;
  std::vector<std::string> warnings;  // E.g. an exposure step without dark frames.
  SensorNoise sensor_noise;   // What the noise estimate measured (the field's noise is from it).
  std::string flat_field;     // The side car divided out; empty: none applied.
  int flat_field_lights = 0;  // LEDs it held a flat field for (the others are taken as uniform).
  int near_lights = 0;        // LEDs with positions, scaled to irradiance at the reference point.
  FieldStorage storage;       // build_field_file: how the file holds the values,
  std::optional<HalfCheck> half_check;  // and (half or auto storage) what half would cost.
  // build_field_file in bands: LEDs whose merge an earlier, killed run had finished
  // (capture/build_checkpoint.h).
  int resumed_lights = 0;
};

ReflectanceField build_field(const Session& session, const BuildOptions& options,
                             BuildSummary* summary = nullptr);

// The field built straight into the file `out` (write_field's format, scanlines), holding no more
// of it than options.memory at once: with less than the whole field, each LED's
// image is spilled in bands of rows to a file beside `out` (it needs the field's size free there,
// and is removed), then each band is read back, turned pixel-major and written. The same values
// and attributes as write_field(build_field(...)), byte for byte. Returns the band height used
// (the field's height: built in memory).
int build_field_file(const Session& session, const BuildOptions& options,
                     const std::filesystem::path& out, const ExrAttributes& attributes = {},
                     BuildSummary* summary = nullptr);

}  // namespace ls::capture
