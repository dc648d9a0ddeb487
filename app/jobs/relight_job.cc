#include "app/jobs/relight_job.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <set>

#include "app/jobs/contact_sheet.h"
#include "app/jobs/ranks.h"
#include "app/jobs/relight_outputs.h"
#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/bands.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/memory.h"
#include "lightstage/run_outputs.h"
#include "physics/envmap.h"
#include "relight/fit/model_edit.h"
#include "relight/fit/model_render.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "relight/sources/map_relight.h"
#include "relight/time/temporal_render.h"

namespace ls::jobs {

namespace fs = std::filesystem;

std::string RelightOptions::validate() const {
  const bool models = !models_file.empty();
  if (!temporal_file.empty()) {
    if (!time_s) return "--temporal: give --time T too";
    if (!std::isfinite(*time_s)) return "--time: expected a finite scene time in seconds";
    if (models) return "--temporal: give either --temporal or --models, not both";
    if (maps.empty() && !light_dir) return "--env: give at least one map (or --light)";
  } else {
    if (time_s) return "--time: renders time-varying models: give --temporal T.exr";
    if (field_file.empty() && !models) return "give a field, --models MAPS.exr, or both";
    if (maps.empty() && !(models && light_dir)) {
      return "--env: give at least one map (or --light with --models)";
    }
    if (light_dir && !models) return "--light: a directional light renders models: give --models";
    if (!edits_file.empty() && !models) {
      return "--edits: edits apply to model maps: give --models MAPS.exr";
    }
  }
  if (light_dir && !(light_dir->allFinite() && light_dir->norm() > 0)) {
    return "--light: expected a non-zero finite direction";
  }
  if (directions_width < 4 || directions_width > 4096 || directions_width % 2 != 0) {
    return "--directions: expected an even number in 4..4096";
  }
  if (exposure_stops) {
    if (std::string problem = exposure_problem(*exposure_stops); !problem.empty()) return problem;
  }
  for (double r : rotations_deg) {
    if (std::string problem = rotation_problem(r); !problem.empty()) return problem;
  }
  if (!(coverage_deg >= 0 && coverage_deg <= 180)) {
    return "--coverage-deg: expected an angle in 0..180 degrees (0: automatic), as a stage file's "
           "coverage";
  }
  if (directions_width != RelightOptions{}.directions_width && !models && temporal_file.empty()) {
    return "--directions: the grid models are lit on: give --models (a field is lit by its LEDs' "
           "cells)";
  }
  if (source_pixels != 0 && source_pixels < relight::MapRelightOptions::kFewestSourcePixels) {
    return "--source-pixels: expected 0 (the field's size) or at least " +
           std::to_string(relight::MapRelightOptions::kFewestSourcePixels) + " (64x64)";
  }
  if (out_dir.empty()) return "--out: give the output directory";
  return {};
}

std::string RelightOptions::to_json() const {
  nlohmann::json j;
  j["field"] = field_file.string();
  j["models"] = models_file.string();
  j["temporal"] = temporal_file.string();
  if (time_s) j["time_s"] = *time_s;
  j["edits"] = edits_file.string();
  for (const fs::path& m : maps) j["env"].push_back(m.string());
  j["rotate_deg"] = rotations_deg;
  if (light_dir) j["light"] = {(*light_dir)[0], (*light_dir)[1], (*light_dir)[2]};
  if (exposure_stops) j["exposure_stops"] = *exposure_stops;
  j["coverage_deg"] = coverage_deg;
  j["bright_sources"] = bright_sources;
  j["source_geometry"] = source_geometry;
  j["source_pixels"] = source_pixels;
  j["memory_bytes"] = memory_bytes;
  j["directions"] = directions_width;
  return j.dump();
}

namespace {

// The options of the relighting under each map: the sources within the memory the run may hold.
relight::MapRelightOptions map_relight_options(const RelightOptions& options) {
  relight::MapRelightOptions out;
  out.coverage_rad = coverage_rad(options);
  out.bright_sources = options.bright_sources;
  out.source_geometry = options.source_geometry;
  out.source_pixels = options.source_pixels;
  out.memory_bytes = memory_given(options);
  return out;
}

// The operator's line for one image: timings, coverage, the sources and why any were left out.
std::string relit_detail(const relight::MapRelit& relit) {
  char detail[200];
  std::snprintf(detail, sizeof detail,
                "light weights %.1f ms, relight %.1f ms; %.2f%% of the map's light falls "
                "outside the dome's coverage and is not represented",
                relit.weights_ms, relit.relight_ms,
                100.0 * relit.lighting.weights.uncovered_fraction());
  std::string line = detail;
  if (!relit.lighting.sources.empty()) {
    char ms[160];
    std::snprintf(ms, sizeof ms, " (normals, %sshadows of the sources' LEDs: %.0f ms, all maps)",
                  relit.geometry ? "the scene's shape, " : "", relit.sources_ms);
    line += "\n    " + relit.lighting.report() + ms;
  }
  if (!relit.note.empty()) line += "\n    " + relit.note + " (--memory)";
  return line;
}

// The field relit under every map and rotation (relight::MapRelighter), read a few MiB at a time
// whatever its size; under MPI each rank relights its bands of rows and rank 0 gathers them.
void relight_field(const RelightOptions& options, RelightSummary& summary,
                   const ProgressFn& progress) {
  capture::FieldStream stream(options.field_file);
  const MapRotations map_rotations(options);
  relight::MapRelighter relighter(stream, map_relight_options(options));
  relight::RowPass pass;
  const Ranks& ranks = Ranks::world();
  if (ranks.size() > 1) {
    // Each rank relights its bands (round robin); rank 0 gathers the others' rows.
    const int rows =
        band_rows_for_ranks(stream.height(), stream.height(), stream.row_alignment(), ranks.size());
    for (int b = ranks.rank(), y0; (y0 = b * rows) < stream.height(); b += ranks.size()) {
      pass.rows.push_back({y0, std::min(stream.height(), y0 + rows)});
    }
    pass.gather = [&options, &ranks, rows](const std::vector<Image*>& images) {
      std::vector<long> no_counts;
      return gather_rows_over_ranks(options, ranks, rows, images, no_counts);
    };
  }
  relight::MapRelitSet relit = relighter.relight_all(map_rotations.all(), pass, progress);
  if (!relit.complete) return;
  summary.field_pass_s = relit.rows_pass_s;
  summary.ranks = ranks.size();
  summary.field_file_bytes = double(fs::file_size(options.field_file));
  RelitWriter writer(options, summary);
  for (std::size_t i = 0; i < relit.relit.size(); ++i) {
    relight::MapRelit& out = relit.relit[i];
    double light = total_luma(out.lighting.weights.irradiance_rgb);
    for (const relight::PlacedSource& source : out.lighting.sources) {
      light += luminance(source.in_stage.irradiance_rgb);
    }
    writer.write(map_rotations.name(i), out.image, relit_detail(out), light);
    report(progress, "relight", long(i + 1), long(relit.relit.size()), map_rotations.name(i));
  }
}

void relight_into(const RelightOptions& options, RelightSummary& summary,
                  const ProgressFn& progress) {
  std::string title;
  const Ranks& ranks = Ranks::world();
  if (!options.temporal_file.empty()) {
    relight_temporal(options, summary, progress);
    title = "temporal: " + options.temporal_file.filename().string();
  } else if (!options.models_file.empty()) {
    relight_models(options, summary, progress);
    title = "models: " + options.models_file.filename().string();
  } else {
    relight_field(options, summary, progress);
    title = "relit: " + options.field_file.filename().string();
  }
  if (!ranks.root()) return;  // Under MPI rank 0 wrote the images.
  if (!options.edits_file.empty()) title += " + " + options.edits_file.filename().string();
  std::vector<Preview> previews;
  for (const RelitImage& image : summary.images) previews.push_back({image.png, image.label});
  summary.contact_sheet = options.out_dir / "contact_sheet.png";
  write_contact_sheet(summary.contact_sheet, previews, title);
}

}  // namespace

RelightSummary relight(const RelightOptions& options, const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("relight: " + problem);
  }
  RelightSummary summary;
  RunOutputs outputs(options.out_dir);  // A run that fails leaves none of its images.
  try {
    relight_into(options, summary, progress);
  } catch (...) {
    for (const RelitImage& image : summary.images) outputs.add(image.exr), outputs.add(image.png);
    outputs.add(summary.contact_sheet);
    throw;
  }
  outputs.keep();
  return summary;
}

}  // namespace ls::jobs
