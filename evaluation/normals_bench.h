#pragma once
// `lightstage bench normals`: every photometric-stereo method (least squares, robust, the
// per-pixel BRDF fit's refined normals, on real sets also with --dim-samples) on every real set
// with ground-truth normals and on the simulator's hard scenes, error against time: normals.csv and
// normals.png (mean angular error against seconds, one series per method, each point labelled by
// its set); on real sets also whether each method's confidence map says where its normal is wrong.
//  - Real sets: each folder of `data` in the DiLiGenT layout holding Normal_gt.mat (the
//    benchmark's ground truth, read with libmatio), imported as `lightstage import` does (its
//    image check included) and scored over the pixels whose true normal is set.
//  - Simulated: the fit sweeps' scenes (evaluation/fit_sweeps.h) at the hardest value of the axes
//    that break photometric stereo (cast shadows, saturation, dead LEDs, grazing normals, noise)
//    at which the robust normals still solve most pixels.
// A method's time is what it takes alone (the fit's includes the robust normals it starts from),
// the median of `repeats` runs on real sets.
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "lightstage/image.h"
#include "lightstage/progress.h"

namespace ls::evaluation {

struct NormalsBenchOptions {
  std::filesystem::path out = "bench-out";
  std::filesystem::path data;        // Folder of DiLiGenT-layout sets.
  std::filesystem::path executable;  // The lightstage executable (the CLI: itself).
  int repeats = 3;                   // Timed runs per method on a real set (median).
  bool quick = false;  // Simulated scenes at 16 rows instead of 32, one run per method.
  std::string validate() const;
};

struct NormalsBenchRow {
  std::string set;     // "ball", "sim shadowed 0.75", ...
  std::string kind;    // "real" or "sim".
  std::string method;  // "least squares", "robust", "fit", "fit --dim-samples" (real sets).
  double mean_deg = 0, median_deg = NAN;
  // Real sets: the mean error over the quarter of the pixels the method is least sure of (its
  // confidence map), and over the quarter it is surest of: whether the confidence says where
  // the normal is wrong.
  double least_confident_deg = NAN, most_confident_deg = NAN;
  // Real sets: of the object's pixels, those left without a normal (counted at 90 degrees);
  // simulated: those flagged (the errors are over the others).
  double flagged_fraction = 0;
  double seconds = 0;
  int pixels = 0;  // Scored.
};

struct NormalsBenchSummary {
  std::vector<NormalsBenchRow> rows;
  std::vector<std::string> real_sets_missing;  // Why no real set was measured, when none was.
  std::filesystem::path csv;                   // normals.csv; normals.png beside it.
};

NormalsBenchSummary run_normals_bench(const NormalsBenchOptions& options,
                                      const ProgressFn& progress = {});

// normals.png beside `csv` (a normals.csv), from it alone.
void write_normals_chart(const std::filesystem::path& csv);

// A DiLiGenT Normal_gt.mat: the H x W unit normals (3 channels, camera frame: x right, y up, z
// toward the camera; (0, 0, 0) off the object). InputError naming the file and the variable when
// it is not one.
Image read_diligent_normals(const std::filesystem::path& mat_file);

}  // namespace ls::evaluation
