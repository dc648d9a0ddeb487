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
#include "lightstage/bands.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/memory.h"
#include "relight/fit/model_edit.h"
#include "relight/fit/model_render.h"
#include "relight/fit/source_relight.h"
#include "relight/lighting/envmap.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
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
  if (exposure_stops && !std::isfinite(*exposure_stops)) return "--exposure: expected a number";
  for (double r : rotations_deg) {
    if (!std::isfinite(r)) return "--rotate: expected finite angles in degrees";
  }
  if (!(std::isfinite(coverage_deg) && coverage_deg >= 0)) {
    return "--coverage-deg: expected a finite angle >= 0";
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
  j["compact_sources"] = compact_sources;
  j["source_geometry"] = source_geometry;
  j["memory_bytes"] = memory_bytes;
  j["directions"] = directions_width;
  return j.dump();
}

namespace {

// One relit image of a field: its map and rotation's light and what relighting it took.
struct Output {
  std::string name;
  double rotation_deg = 0;
  relight::SplitLighting lighting;
  double weights_ms = 0, relight_ms = 0;
  Image relit;
};

// Rendering compact sources holds full-size images (relight::FieldSources::bytes_needed): 11 GiB
// for one source at 24 MP. When that is over options.memory_bytes (0: half the memory available),
// the sources are relit by the LED cells with the rest of their maps instead, and the returned
// line says why (empty when they fit).

std::size_t sources_bytes(const capture::ReflectanceField& header,
                          const std::vector<Output>& outputs, std::size_t source_leds,
                          bool geometry) {
  int triangles = 0;
  for (const Output& out : outputs) {
    for (const auto& source : out.lighting.sources) triangles += source.triangle.has_value();
  }
  return relight::FieldSources::bytes_needed(header.width(), header.height(), int(source_leds),
                                             triangles, geometry ? header.num_lights() : 0);
}

// What is left out for want of memory, one line: `what` would hold `need` bytes.
std::string over_memory(const char* what, std::size_t need, std::size_t may,
                        const capture::ReflectanceField& header) {
  char line[300];
  std::snprintf(line, sizeof line,
                "%s would hold %.0f MiB for this %dx%d field, over the %.0f MiB it may use "
                "(--memory)",
                what, double(need) / (1 << 20), header.width(), header.height(),
                double(may) / (1 << 20));
  return line;
}

// The sources fit with the geometry, or without it, or (the returned line says why) not at all.
std::string fit_sources_in_memory(const RelightOptions& options,
                                  const capture::ReflectanceField& header,
                                  std::vector<Output>& outputs, std::set<int>& source_leds,
                                  bool& geometry) {
  if (source_leds.empty()) return {};
  const std::size_t may = memory_given(options);
  geometry = options.source_geometry;
  std::string note;
  if (geometry) {
    const std::size_t need = sources_bytes(header, outputs, source_leds.size(), true);
    if (need <= may) return {};
    note = over_memory("compact sources' shadows by the LEDs' flows alone: the scene's shape", need,
                       may, header);
    geometry = false;
  }
  const std::size_t need = sources_bytes(header, outputs, source_leds.size(), false);
  if (need <= may) return note;
  MapRotations map_rotations(options);
  size_t i = 0;
  map_rotations.for_each(
      [&](const relight::EnvironmentMap& map, double rotation, const std::string&) {
        outputs[i++].lighting =
            relight::split_lighting(map, header.lights(), rotation, coverage_rad(options), false);
      });
  source_leds.clear();
  return over_memory("compact sources relit by the LED cells: rendering them at their direction",
                     need, may, header);
}

// The field relit under every map and rotation, read once a few MiB at a time (FieldStream's rows
// as the file holds them) whatever its size: each piece is relit under every map before the next
// is read, into full-size outputs (3 floats per pixel each).
void relight_field(const RelightOptions& options, RelightSummary& summary,
                   const ProgressFn& progress) {
  capture::FieldStream stream(options.field_file);
  const capture::ReflectanceField& header = stream.header();
  std::vector<Output> outputs;
  std::set<int> source_leds;
  MapRotations map_rotations(options);
  map_rotations.for_each(
      [&](const relight::EnvironmentMap& map, double rotation, const std::string& name) {
        const auto t0 = Clock::now();
        Output out{name, rotation,
                   relight::split_lighting(map, header.lights(), rotation, coverage_rad(options),
                                           options.compact_sources)};
        out.weights_ms = ms_between(t0, Clock::now());
        out.relit = Image(header.width(), header.height(), 3);
        for (const int led : out.lighting.leds()) source_leds.insert(led);
        outputs.push_back(std::move(out));
      });
  bool geometry = false;
  const std::string sources_note =
      fit_sources_in_memory(options, header, outputs, source_leds, geometry);
  // The field's rows as the file holds them, in pieces of about 8 MiB: relighting sums over each
  // pixel's values, so it needs no pixel-major band (and no memory for one: --memory is moot).
  const auto pass_start = Clock::now();
  const auto relight_rows = [&](int y0, int y1) {
    stream.read_rows_planar(y0, y1, [&](const capture::PlanarRows& rows) {
      for (Output& out : outputs) {
        const auto t0 = Clock::now();
        relight::relight_rows_into(rows, out.lighting.weights.irradiance_rgb, out.relit);
        out.relight_ms += ms_between(t0, Clock::now());
      }
      const int done = rows.first_row + rows.rows;
      if (done < header.height()) report(progress, "relight (rows)", done, header.height());
    });
  };
  const Ranks& ranks = Ranks::world();
  if (ranks.size() == 1) {
    relight_rows(0, header.height());
  } else {
    // Each rank relights its bands (round robin); rank 0 gathers the others' rows.
    const int rows =
        band_rows_for_ranks(header.height(), header.height(), stream.row_alignment(), ranks.size());
    for (int b = ranks.rank(), y0; (y0 = b * rows) < header.height(); b += ranks.size()) {
      relight_rows(y0, std::min(header.height(), y0 + rows));
    }
    std::vector<Image*> images;
    images.reserve(outputs.size());
    for (Output& out : outputs) images.push_back(&out.relit);
    std::vector<long> no_counts;
    if (!gather_rows_over_ranks(options, ranks, rows, images, no_counts)) return;
  }
  summary.field_pass_s = ms_between(pass_start, Clock::now()) / 1e3;
  summary.ranks = ranks.size();
  summary.field_file_bytes = double(fs::file_size(options.field_file));
  double sources_ms = 0;
  if (!source_leds.empty()) {
    // Compact sources need the field's normals and the images of the LEDs around them: a second
    // pass, in bands.
    const auto t0 = Clock::now();
    report(progress, "compact sources (normals)", 0, 1);
    // Bands within what the sources' images leave of the memory given.
    const std::size_t band_bytes =
        memory_given(options) - sources_bytes(header, outputs, source_leds.size(), geometry);
    const relight::FieldSources sources(
        header, stream.bands(stream.rows_within(band_bytes)),
        {source_leds.begin(), source_leds.end()}, geometry, [&](int done, int total) {
          report(progress, "compact sources (the scene's shape)", done, total);
        });
    for (Output& out : outputs) sources.add(out.lighting, out.relit);
    sources_ms = ms_between(t0, Clock::now());
  }
  RelitWriter writer(options, summary);
  long done = 0;
  for (Output& out : outputs) {
    char detail[200];
    std::snprintf(detail, sizeof detail,
                  "light weights %.1f ms, relight %.1f ms; %.2f%% of the map's light falls "
                  "outside the dome's coverage and is not represented",
                  out.weights_ms, out.relight_ms,
                  100.0 * out.lighting.weights.uncovered_fraction());
    std::string line = detail;
    if (!out.lighting.sources.empty()) {
      char ms[160];
      std::snprintf(ms, sizeof ms, " (normals, %sshadows of the sources' LEDs: %.0f ms, all maps)",
                    geometry ? "the scene's shape, " : "", sources_ms);
      line += "\n    " + out.lighting.report() + ms;
    }
    if (!sources_note.empty()) line += "\n    " + sources_note;
    double light = total_luma(out.lighting.weights.irradiance_rgb);
    for (const relight::PlacedSource& source : out.lighting.sources) {
      light += luma(source.in_stage.irradiance_rgb);
    }
    writer.write(out.name, out.relit, line, light);
    report(progress, "relight", ++done, long(outputs.size()), out.name);
  }
}

}  // namespace

RelightSummary relight(const RelightOptions& options, const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("relight: " + problem);
  }
  RelightSummary summary;
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
  if (!ranks.root()) return summary;  // Under MPI rank 0 wrote the images.
  if (!options.edits_file.empty()) title += " + " + options.edits_file.filename().string();
  std::vector<Preview> previews;
  for (const RelitImage& image : summary.images) previews.push_back({image.png, image.label});
  summary.contact_sheet = options.out_dir / "contact_sheet.png";
  write_contact_sheet(summary.contact_sheet, previews, title);
  return summary;
}

}  // namespace ls::jobs
