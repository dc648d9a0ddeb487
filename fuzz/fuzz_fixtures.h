#pragma once
// Small, valid lightstage objects for the fuzz targets: what the edit targets apply their edits
// to, and what the seed generator (make_seeds.cc) writes through the project's own writers.
#include <filesystem>

#include "capture/field.h"
#include "lightstage/session.h"
#include "lightstage/stage.h"
#include "relight/fit/fit.h"
#include "relight/time/temporal_fit.h"

namespace ls::fuzz {

inline constexpr int kFixtureWidth = 4;
inline constexpr int kFixtureHeight = 3;

// A 4 x 3 field of `num_lights` LEDs over the upper hemisphere: one dead, one near (with a
// position and the field's view), one with a saturation ceiling; measured noise; scene time.
capture::ReflectanceField small_field(int num_lights);

// 4 x 3 model maps with every model (and a flagged pixel), two basis materials.
relight::ModelMaps small_model_maps();

// 4 x 3 temporal maps with every process (and a flagged pixel), four steps.
relight::TemporalMaps small_temporal_maps();

// A stage of 3 LEDs, an 8 x 4 camera, 2 exposures, 2 dark frames and 2 time steps: the session
// target's and its seeds'.
Stage small_stage();
// The frame a simulated capture of small_stage() would save for `planned` (deterministic, so that
// what the seeds journaled matches what the session target puts on disk).
CapturedFrame small_frame(const PlannedFrame& planned);
// Every planned frame of `stage` as SESSION/frames/<name>.png.
void write_small_frames(const std::filesystem::path& session_dir, const Stage& stage);

// A 4 x 3 PNG, the left half white: an edit file's mask, an .lp file's image.
void write_half_white_png(const std::filesystem::path& path);
// The folder an edit file is read from: work_dir(), holding mask.png (write_half_white_png) for
// "mask" selections; written on the first call.
const std::filesystem::path& edits_dir();

}  // namespace ls::fuzz
