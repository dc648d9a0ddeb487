#include "evaluation/normals_bench.h"

#include <matio.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <memory>

#include "evaluation/bench_support.h"
#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "evaluation/fit_sweeps.h"
#include "lightstage/angles.h"
#include "lightstage/errors.h"
#include "relight/fit/fit.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

namespace {

// The methods as a user runs them: the lightstage command after `import`, and its output file.
struct Method {
  const char* name;
  std::vector<std::string> command;  // After the executable; the field and --out follow.
  bool model_maps;                   // The output is fit's model maps (else normals' EXR).
};
const Method kMethods[] = {{"least squares", {"normals", "--method", "ls"}, false},
                           {"robust", {"normals"}, false},
                           {"fit", {"fit"}, true},
                           {"fit --dim-samples", {"fit", "--dim-samples"}, true}};

// Over the ground truth's object: the estimate's error in degrees (a pixel the method left
// without a normal counts 90 degrees, as the published tables count every mask pixel), and the
// fraction so left.
NormalsBenchRow score(const Image& truth, const Image& estimate, int nx, int confidence) {
  NormalsBenchRow row;
  std::vector<double> errors;
  std::vector<std::pair<float, double>> by_confidence;  // confidence, error
  int flagged = 0;
  for (int y = 0; y < truth.height; ++y) {
    for (int x = 0; x < truth.width; ++x) {
      const Eigen::Vector3d t(truth.at(x, y, 0), truth.at(x, y, 1), truth.at(x, y, 2));
      if (t.norm() < 0.5) continue;  // Off the object.
      const Eigen::Vector3d n(estimate.at(x, y, nx), estimate.at(x, y, nx + 1),
                              estimate.at(x, y, nx + 2));
      flagged += n.norm() == 0;
      const double cosine = n.norm() > 0 ? n.normalized().dot(t.normalized()) : 0.0;
      errors.push_back(std::acos(std::clamp(cosine, -1.0, 1.0)) * kRadToDeg);
      by_confidence.emplace_back(estimate.at(x, y, confidence), errors.back());
    }
  }
  row.pixels = int(errors.size());
  if (errors.empty()) return row;
  const auto mean_of = [](auto begin, auto end) {
    double sum = 0;
    for (auto it = begin; it != end; ++it) sum += it->second;
    return sum / double(end - begin);
  };
  std::stable_sort(by_confidence.begin(), by_confidence.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  const auto quarter = std::ptrdiff_t(by_confidence.size() / 4);
  if (quarter > 0) {
    row.least_confident_deg = mean_of(by_confidence.begin(), by_confidence.begin() + quarter);
    row.most_confident_deg = mean_of(by_confidence.end() - quarter, by_confidence.end());
  }
  row.mean_deg = mean_of(by_confidence.begin(), by_confidence.end());
  std::nth_element(errors.begin(), errors.begin() + std::ptrdiff_t(errors.size() / 2),
                   errors.end());
  row.median_deg = errors[errors.size() / 2];
  row.flagged_fraction = double(flagged) / double(row.pixels);
  return row;
}

int channel_index(const Image& image, const std::string& name, const fs::path& file) {
  const auto& names = image.channel_names;
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) throw InputError(file.string() + ": no channel " + name);
  return int(it - names.begin());
}

// One real set: imported, then each method run `repeats` times (median seconds) and scored.
void bench_real_set(const fs::path& set, const NormalsBenchOptions& options, const fs::path& work,
                    std::vector<NormalsBenchRow>& rows) {
  const Image truth = read_diligent_normals(set / "Normal_gt.mat");
  const std::string name = set.filename().string();
  const fs::path& exe = options.executable;
  const fs::path field = work / (name + ".exr");
  run_process({exe, "import", set, "--quiet", "--out", field}, work / (name + ".import.log"));
  for (const Method& method : kMethods) {
    const fs::path out = work / (name + "." + (method.model_maps ? "fit" : "normals") + ".exr");
    std::vector<double> seconds;
    for (int r = 0; r < options.repeats; ++r) {
      std::vector<std::string> argv{exe};
      argv.insert(argv.end(), method.command.begin(), method.command.end());
      argv.insert(argv.end(), {field.string(), "--quiet", "--out", out.string()});
      seconds.push_back(run_process(argv, work / (name + ".log")).seconds);
    }
    std::sort(seconds.begin(), seconds.end());
    const Image estimate = method.model_maps ? relight::read_model_maps(out).maps : read_image(out);
    if (estimate.width != truth.width || estimate.height != truth.height) {
      throw InputError(set.string() + ": Normal_gt.mat is " + std::to_string(truth.width) + "x" +
                       std::to_string(truth.height) + ", the images " +
                       std::to_string(estimate.width) + "x" + std::to_string(estimate.height));
    }
    NormalsBenchRow row =
        method.model_maps ? score(truth, estimate, relight::kMapNormalX, relight::kMapConfidence)
                          : score(truth, estimate, channel_index(estimate, "normal.x", out),
                                  channel_index(estimate, "confidence", out));
    row.set = name;
    row.kind = "real";
    row.method = method.name;
    row.seconds = seconds[seconds.size() / 2];
    rows.push_back(row);
  }
}

// The fit sweeps' scenes at the hardest value of the axes that break photometric stereo at which
// the robust normals still solve most pixels (95% of the LEDs dead leaves almost none).
void bench_sim_scenes(const NormalsBenchOptions& options, const ProgressFn& progress,
                      std::vector<NormalsBenchRow>& rows) {
  FitSweepOptions sweeps;
  sweeps.quick = true;
  sweeps.height = options.quick ? 16 : 32;
  sweeps.width = 3 * sweeps.height;
  sweeps.axes = {SweepAxis::kShadowedFraction, SweepAxis::kSaturation, SweepAxis::kDeadLeds,
                 SweepAxis::kGrazingNormals, SweepAxis::kNoise};
  sweeps.progress = progress;
  const std::vector<SweepPoint> points = run_fit_sweeps(sweeps);
  for (const SweepAxis axis : sweeps.axes) {
    const auto hardest = std::find_if(points.rbegin(), points.rend(), [&](const SweepPoint& p) {
      return p.axis == axis && p.robust.mean_deg && p.robust.flagged_fraction < 0.5;
    });
    if (hardest == points.rend()) continue;
    const SweepPoint& p = *hardest;
    char set[64];
    std::snprintf(set, sizeof set, "sim %s %g", to_string(p.axis), p.value);
    // The fit starts from the robust normals: its time includes theirs.
    const struct {
      const char* method;
      const NormalScore& score;
      double seconds;
    } scores[] = {{"least squares", p.least_squares, p.least_squares_seconds},
                  {"robust", p.robust, p.robust_seconds},
                  {"fit", p.fit, p.robust_seconds + p.fit_seconds}};
    for (const auto& [method, score, seconds] : scores) {
      NormalsBenchRow row;
      row.set = set;
      row.kind = "sim";
      row.method = method;
      // Over the pixels not flagged (fit sweeps' scores).
      row.mean_deg = score.mean_deg.value_or(NAN);
      row.flagged_fraction = score.flagged_fraction;
      row.seconds = seconds;
      row.pixels = p.surface_pixels;
      rows.push_back(row);
    }
  }
}

void write_csv(const fs::path& csv, const std::vector<NormalsBenchRow>& rows) {
  std::ofstream out(csv);
  out << "set,kind,method,mean_deg,median_deg,flagged,seconds,pixels,least_confident_deg,"
         "most_confident_deg\n";
  const auto number = [](double v) { return std::isnan(v) ? std::string() : std::to_string(v); };
  for (const NormalsBenchRow& r : rows) {
    out << csv_field(r.set) << ',' << r.kind << ',' << csv_field(r.method) << ',' << r.mean_deg
        << ',' << number(r.median_deg) << ',' << r.flagged_fraction << ',' << r.seconds << ','
        << r.pixels << ',' << number(r.least_confident_deg) << ',' << number(r.most_confident_deg)
        << '\n';
  }
  if (!out) throw InputError(csv.string() + ": cannot write");
}

}  // namespace

std::string NormalsBenchOptions::validate() const {
  if (!fs::exists(executable)) {
    return "bench normals: the lightstage executable: " + executable.string() + " not found";
  }
  if (repeats < 1 || repeats > 100) {
    return "bench normals: --repeats: expected 1..100, got " + std::to_string(repeats);
  }
  return {};
}

Image read_diligent_normals(const fs::path& mat_file) {
  const std::unique_ptr<mat_t, int (*)(mat_t*)> mat(Mat_Open(mat_file.c_str(), MAT_ACC_RDONLY),
                                                    Mat_Close);
  if (!mat) throw InputError(mat_file.string() + ": cannot open as a MATLAB file");
  const std::unique_ptr<matvar_t, void (*)(matvar_t*)> var(Mat_VarRead(mat.get(), "Normal_gt"),
                                                           Mat_VarFree);
  if (!var) throw InputError(mat_file.string() + ": no variable Normal_gt");
  if (var->rank != 3 || var->dims[2] != 3 || var->class_type != MAT_C_DOUBLE || !var->data) {
    throw InputError(mat_file.string() +
                     ": Normal_gt: expected an H x W x 3 array of doubles (unit normals)");
  }
  const int height = int(var->dims[0]), width = int(var->dims[1]);
  Image normals(width, height, 3);
  const auto* data = static_cast<const double*>(var->data);
  // MATLAB arrays are column-major: element (y, x, c) at y + H * (x + W * c).
  for (int c = 0; c < 3; ++c) {
    for (int x = 0; x < width; ++x) {
      for (int y = 0; y < height; ++y) {
        const double v = data[std::size_t(y) + std::size_t(height) * (x + std::size_t(width) * c)];
        if (!std::isfinite(v)) {
          throw InputError(mat_file.string() + ": Normal_gt: not finite at row " +
                           std::to_string(y + 1) + ", column " + std::to_string(x + 1));
        }
        normals.at(x, y, c) = float(v);
      }
    }
  }
  return normals;
}

void write_normals_chart(const fs::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  std::vector<ChartSeries> series = series_by("method", table.distinct("method"));
  for (ChartSeries& s : series) s.labels.column = "set";
  write_chart(fs::path(csv).replace_filename("normals.png"),
              {.csv = csv,
               .x = "seconds",
               .y = "mean_deg",
               .series = series,
               .title = "Photometric-stereo normals: error against time (labels: the set)",
               .x_label = "seconds (as the user runs it; simulated scenes: in process)",
               .y_label = "mean angular error of the normal, deg",
               .log_x = true,
               .log_y = true,
               .lines = false});
}

NormalsBenchSummary run_normals_bench(const NormalsBenchOptions& options,
                                      const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  const fs::path work = options.out / "normals-work";
  fs::create_directories(work);
  NormalsBenchSummary summary;
  std::vector<fs::path> sets;
  if (fs::is_directory(options.data)) {
    for (const auto& entry : fs::directory_iterator(options.data)) {
      if (fs::exists(entry.path() / "Normal_gt.mat")) sets.push_back(entry.path());
    }
  }
  std::sort(sets.begin(), sets.end());
  if (sets.empty()) {
    summary.real_sets_missing.push_back(options.data.string() +
                                        ": no DiLiGenT-layout set with Normal_gt.mat");
  }
  for (size_t i = 0; i < sets.size(); ++i) {
    report(progress, "normals (real sets)", long(i), long(sets.size()), sets[i].filename());
    bench_real_set(sets[i], options, work, summary.rows);
  }
  report(progress, "normals (real sets)", long(sets.size()), long(sets.size()), {});
  bench_sim_scenes(options, progress, summary.rows);
  fs::remove_all(work);
  summary.csv = options.out / "normals.csv";
  write_csv(summary.csv, summary.rows);
  write_normals_chart(summary.csv);
  return summary;
}

}  // namespace ls::evaluation
