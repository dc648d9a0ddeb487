#include "app/jobs/import_job.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>

#include "app/jobs/ranks.h"
#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/run_outputs.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

// What the import did, as given or as the format's default (the transfer curve undone; its
// exponent only for a gamma curve).
std::string options_json(const fs::path& source, capture::OlatFormat format,
                         const capture::OlatImportOptions& options) {
  nlohmann::json j;
  j["source"] = source.string();
  const capture::TransferCurve transfer =
      options.transfer.value_or(capture::default_transfer(format));
  j["transfer"] = capture::to_string(transfer);
  if (transfer == capture::TransferCurve::kGamma) j["gamma"] = options.gamma;
  j["max_size"] = options.max_size;
  j["drop_saturated"] = options.zero_saturated;
  j["keep_all"] = options.keep_all;
  j["scene_time_s"] = options.scene_time_s;
  if (!options.spheres.outlines.empty()) {
    nlohmann::json circles = nlohmann::json::array();
    for (const capture::SphereOutline& o : options.spheres.outlines) {
      circles.push_back({o.center_px.x(), o.center_px.y(), o.radius_px});
    }
    j["spheres"] = {{"circles", circles},
                    {"radius_m", options.spheres.radius_m},
                    {"focal_length_px", options.spheres.focal_length_px}};
  }
  if (!options.stage_file.empty()) j["stage"] = options.stage_file.string();
  return j.dump();
}

// The image of the field's light nearest the camera, read back from the field file: the preview
// when the image check left out the one seen first. `light` gets its index in the set.
Image frontal_light_image(const fs::path& field_file, int& light) {
  capture::FieldStream stream(field_file);
  const capture::ReflectanceField& header = stream.header();
  int frontal = 0;
  for (int l = 1; l < header.num_lights(); ++l) {
    if (header.lights()[size_t(l)].dir_in_stage.z() >
        header.lights()[size_t(frontal)].dir_in_stage.z()) {
      frontal = l;
    }
  }
  light = header.lights()[size_t(frontal)].led_id;  // Ids are the set's order.
  Image image(header.width(), header.height(), 3);
  stream.bands(stream.band_rows(MemoryBudget(MemoryBudget::kImageSetBytes)))(
      [&](const capture::ReflectanceField& band) {
        for (int y = 0; y < band.height(); ++y) {
          for (int x = 0; x < band.width(); ++x) {
            const float* rgb = band.pixel(x, y) + std::ptrdiff_t(3) * frontal;
            std::copy_n(rgb, 3, &image.at(x, band.first_row() + y, 0));
          }
        }
      });
  return image;
}

}  // namespace

ImportJobSummary import_set(const fs::path& source, const fs::path& out,
                            capture::OlatImportOptions options, const MemoryBudget& memory,
                            const ProgressFn& progress) {
  ImportJobSummary summary;
  summary.format = capture::detect_olat_format(source);
  options.progress = progress;
  // The preview: the light nearest the camera (+Z), the most evenly lit of the images (the first
  // of equals), kept as the images are read.
  std::mutex preview_mutex;
  double preview_z = -2;
  std::vector<float> preview_rgb;
  const auto keep_frontal = [&](int light, const Eigen::Vector3d& dir,
                                const std::vector<float>& rgb) {
    const std::lock_guard lock(preview_mutex);
    if (dir.z() > preview_z || (dir.z() == preview_z && light < summary.preview_light)) {
      preview_z = dir.z();
      summary.preview_light = light;
      preview_rgb = rgb;
    }
  };
  const Ranks& ranks = Ranks::world();
  summary.band_rows = capture::import_olat_to_file(
      source, options, out, {{kOptionsAttribute, options_json(source, summary.format, options)}},
      MemoryBudget(memory.bytes_or(MemoryBudget::kImageSetBytes)), keep_frontal, &summary.import,
      ranks.split());
  summary.ranks = ranks.size();
  if (!ranks.root()) return summary;  // Rank 0 wrote the field (and writes the preview).
  summary.lights = summary.import.lights();
  summary.mebibytes = capture::ReflectanceField::bytes_for(summary.import.width,
                                                           summary.import.height, summary.lights) /
                      1048576.0;
  Image preview(summary.import.width, summary.import.height, 3);
  preview.pixels = std::move(preview_rgb);
  const std::vector<int>& left_out = summary.import.left_out_lights;
  if (std::find(left_out.begin(), left_out.end(), summary.preview_light) != left_out.end()) {
    preview = frontal_light_image(out, summary.preview_light);
  }
  summary.preview = out;
  summary.preview.replace_extension(".preview.png");
  write_png_preview(summary.preview, preview, auto_exposure_stops(preview));
  return summary;
}

std::vector<fs::path> series_sets(const std::vector<fs::path>& sources) {
  if (sources.size() != 1 || !fs::is_directory(sources[0])) return sources;
  try {
    capture::detect_olat_format(sources[0]);
    return sources;  // One set.
  } catch (const InputError&) {
  }
  std::vector<fs::path> sets;
  for (const auto& entry : fs::directory_iterator(sources[0])) {
    if (entry.is_directory()) sets.push_back(entry.path());
  }
  // A folder of .lp files (not of sets): why it is none of them, from the format's own check.
  if (sets.empty()) (void)capture::detect_olat_format(sources[0]);
  if (sets.empty()) {
    throw InputError(sources[0].string() +
                     ": expected an .lp set, a DiLiGenT folder, or a folder of them (one per time "
                     "step), found none");
  }
  std::sort(sets.begin(), sets.end());
  return sets;
}

namespace {

// The time steps of one scene are lit alike: one format (an .lp set's sRGB images beside a
// DiLiGenT set's linear ones would be linearised unlike) and the same light directions (else the
// steps' samples are not of the same lights). Refused naming the first step that differs, before
// anything is written.
void check_one_dome(const std::vector<fs::path>& sets, const capture::OlatImportOptions& options) {
  const capture::OlatFormat format = capture::detect_olat_format(sets[0]);
  const capture::ReflectanceField first = capture::olat_header(sets[0], options);
  for (size_t i = 1; i < sets.size(); ++i) {
    const capture::OlatFormat step_format = capture::detect_olat_format(sets[i]);
    if (step_format != format) {
      throw InputError(sets[i].string() + ": time step " + std::to_string(i) + ": expected " +
                       capture::to_string(format) + " like " + sets[0].string() + ", got " +
                       capture::to_string(step_format) +
                       ": the steps of one time-lapse are one kind of set");
    }
    const capture::ReflectanceField step = capture::olat_header(sets[i], options);
    if (step.num_lights() != first.num_lights()) continue;  // Said with the step's size, below.
    for (int l = 0; l < first.num_lights(); ++l) {
      const Eigen::Vector3d a = first.lights()[size_t(l)].dir_in_stage.normalized();
      const Eigen::Vector3d b = step.lights()[size_t(l)].dir_in_stage.normalized();
      constexpr double kSameDirectionDeg = 0.1;  // Rounding in an .lp's text, no more.
      const double degrees = std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180 / M_PI;
      if (degrees > kSameDirectionDeg) {
        char text[160];
        std::snprintf(text, sizeof text,
                      ": time step %zu: light %d is %.2f degrees from light %d of ", i, l + 1,
                      degrees, l + 1);
        throw InputError(sets[i].string() + text + sets[0].string() +
                         ": the steps of one time-lapse are lit from the same directions");
      }
    }
  }
}

}  // namespace

ImportSeriesSummary import_series(const std::vector<fs::path>& sources,
                                  const std::vector<double>& times_s, double interval_s,
                                  const fs::path& out_dir,
                                  const capture::OlatImportOptions& options,
                                  const MemoryBudget& memory, const ProgressFn& progress) {
  ImportSeriesSummary out;
  out.sets = series_sets(sources);
  const size_t steps = out.sets.size();
  if (!times_s.empty() && times_s.size() != steps) {
    throw InputError("import: --time: expected one time per set (" + std::to_string(steps) +
                     " sets), got " + std::to_string(times_s.size()));
  }
  if (steps < 2) {
    throw InputError("import: --interval: a time-lapse needs two sets or more, got " +
                     std::to_string(steps) + " (one set: give its scene time with --time S)");
  }
  // Three centuries: beyond that it is a typing slip (1e308 overflows the later steps' times).
  if (interval_s > 1e10) {
    char got[32];
    std::snprintf(got, sizeof got, "%g", interval_s);
    throw InputError(
        "import: --interval: expected at most 1e10 s (three centuries) between sets, got " +
        std::string(got) + " s");
  }
  if (times_s.empty() && !(interval_s > 0 && std::isfinite(interval_s))) {
    throw InputError("import: " + std::to_string(steps) +
                     " sets: give each its scene time (--time S...) or the interval between them "
                     "(--interval S)");
  }
  for (size_t i = 0; i < steps; ++i) {
    out.times_s.push_back(times_s.empty() ? double(i) * interval_s : times_s[i]);
    if (i > 0 && !(out.times_s[i] > out.times_s[i - 1])) {
      throw InputError("import: --time: expected increasing times, got " +
                       std::to_string(out.times_s[i]) + " s after " +
                       std::to_string(out.times_s[i - 1]) + " s (" + out.sets[i].string() + ")");
    }
  }
  check_one_dome(out.sets, options);
  RunOutputs outputs(out_dir);  // A series refused part-way leaves no fields.
  fs::create_directories(out_dir);
  for (size_t i = 0; i < steps; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "field_t%03zu.exr", i);
    capture::OlatImportOptions step = options;
    step.scene_time_s = out.times_s[i];
    // The steps of a time-lapse are fitted over the same lights: an image found inconsistent is
    // listed, not left out of one step.
    step.leave_out_inconsistent = false;
    out.fields.push_back(out_dir / name);
    outputs.add(out.fields.back());
    outputs.add(fs::path(out.fields.back()).replace_extension(".preview.png"));
    out.steps.push_back(import_set(out.sets[i], out.fields.back(), step, memory, {}));
    // One scene over time: every step the same pixels under the same number of lights.
    const capture::OlatImportSummary& first = out.steps.front().import;
    const capture::OlatImportSummary& now = out.steps.back().import;
    if (now.width != first.width || now.height != first.height || now.images != first.images) {
      const auto shape = [](const capture::OlatImportSummary& s) {
        return std::to_string(s.width) + "x" + std::to_string(s.height) + ", " +
               std::to_string(s.images) + " images";
      };
      throw InputError(out.sets[i].string() + ": expected a set like " + out.sets[0].string() +
                       " (" + shape(first) + ": the time steps of one scene), got " + shape(now));
    }
    report(progress, "import (time steps)", long(i + 1), long(steps), out.sets[i].filename());
  }
  outputs.keep();
  return out;
}

}  // namespace ls::jobs
