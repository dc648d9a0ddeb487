#include "app/jobs/relight_job.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <set>

#include "app/jobs/contact_sheet.h"
#include "app/jobs/fit_bands.h"
#include "app/jobs/ranks.h"
#include "capture/field.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/memory.h"
#include "lightstage/scratch_file.h"
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
  j["memory_bytes"] = memory_bytes;
  j["directions"] = directions_width;
  return j.dump();
}

namespace {

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Output name of a map and rotation: the map's stem, its folder when two maps share a stem, and
// the rotation when there is one.
std::string output_name(const fs::path& map_path, double rotation, bool several_rotations,
                        std::set<std::string>& used_names) {
  std::string name = map_path.stem().string();
  if (used_names.count(name)) name = map_path.parent_path().filename().string() + "_" + name;
  if (several_rotations || rotation != 0.0) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "_rot%03d", int(std::lround(rotation)));
    name += buf;
  }
  used_names.insert(name);
  return name;
}

// Walks the maps and rotations in output order, loading each map once.
class MapRotations {
 public:
  // Every map is read once here, so that a bad one stops the run before any image is written.
  explicit MapRotations(const RelightOptions& options) : options_(options) {
    for (const fs::path& map_path : options_.maps) relight::EnvironmentMap::load(map_path);
  }
  long count() const { return long(options_.maps.size() * options_.rotations_deg.size()); }
  template <typename Fn>  // fn(map, rotation_deg, output name)
  void for_each(Fn&& fn) {
    for (const fs::path& map_path : options_.maps) {
      const relight::EnvironmentMap map = relight::EnvironmentMap::load(map_path);
      for (double rotation : options_.rotations_deg) {
        fn(map, rotation,
           output_name(map_path, rotation, options_.rotations_deg.size() > 1, used_names_));
      }
    }
  }

 private:
  const RelightOptions& options_;
  std::set<std::string> used_names_;  // Maps from different folders may share a file name.
};

// A preview is exposed by its own highlights (auto_exposure_stops), but never more than
// kDarkSceneStops brighter than a white Lambertian surface that all of the light reaches at normal
// incidence (radiance sum E / pi at 0.9): a scene that a map leaves dark (lit from behind the
// backdrop) reads as dark, not as its noise amplified to full scale.
constexpr double kDarkSceneStops = 2;

double preview_exposure(const Image& relit, double light_luma) {
  const double own = auto_exposure_stops(relit);
  if (!(light_luma > 0) || !std::isfinite(light_luma)) return own;
  return std::min(own, -std::log2(light_luma / M_PI / 0.9) + kDarkSceneStops);
}

double luma(const Eigen::Vector3d& rgb) {
  return 0.2126 * rgb.x() + 0.7152 * rgb.y() + 0.0722 * rgb.z();
}

double total_luma(const std::vector<Eigen::Vector3f>& irradiance_rgb) {
  double sum = 0;
  for (const Eigen::Vector3f& e : irradiance_rgb) sum += luma(e.cast<double>());
  return sum;
}

// RGB triplets, one per light (LightWeights::irradiance_rgb).
double total_luma(const std::vector<float>& irradiance_rgb) {
  double sum = 0;
  for (size_t i = 0; i + 2 < irradiance_rgb.size(); i += 3) {
    sum += luma(Eigen::Vector3d(irradiance_rgb[i], irradiance_rgb[i + 1], irradiance_rgb[i + 2]));
  }
  return sum;
}

class RelitWriter {
 public:
  RelitWriter(const RelightOptions& options, RelightSummary& summary)
      : options_(options), summary_(summary), attributes_{{kOptionsAttribute, options.to_json()}} {}
  // The output directory is made with the first image: a run that fails before leaves none.
  // light_luma: the lighting's total irradiance (luminance, at normal incidence), for the PNG's
  // exposure (preview_exposure); 0 when unknown.
  void write(const std::string& name, Image& relit, std::string detail = {},
             double light_luma = 0) {
    fs::create_directories(options_.out_dir);
    relit.channel_names = {"R", "G", "B"};
    RelitImage out{options_.out_dir / (name + ".exr"), options_.out_dir / (name + ".png"), name,
                   std::move(detail)};
    write_exr(out.exr, relit, ExrPixelType::kFloat, attributes_);
    write_png_preview(out.png, relit,
                      options_.exposure_stops.value_or(preview_exposure(relit, light_luma)));
    summary_.images.push_back(std::move(out));
  }

 private:
  const RelightOptions& options_;
  RelightSummary& summary_;
  ExrAttributes attributes_;
};

struct FieldLights {
  std::vector<Eigen::Vector3d> dirs;
  std::vector<bool> valid;
};

FieldLights field_lights(const capture::ReflectanceField& field) {
  FieldLights out;
  for (const auto& light : field.lights()) {
    out.dirs.push_back(light.dir_in_stage);
    out.valid.push_back(light.valid);
  }
  return out;
}

double coverage_rad(const RelightOptions& options) { return options.coverage_deg * M_PI / 180.0; }

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
std::size_t memory_given(const RelightOptions& options) {
  return options.memory_bytes > 0 ? options.memory_bytes : available_memory_bytes() / 2;
}

std::size_t sources_bytes(const capture::ReflectanceField& header,
                          const std::vector<Output>& outputs, std::size_t source_leds) {
  int triangles = 0;
  for (const Output& out : outputs) {
    for (const auto& source : out.lighting.sources) triangles += source.triangle.has_value();
  }
  return relight::FieldSources::bytes_needed(header.width(), header.height(), int(source_leds),
                                             triangles);
}

std::string fit_sources_in_memory(const RelightOptions& options,
                                  const capture::ReflectanceField& header,
                                  std::vector<Output>& outputs, std::set<int>& source_leds) {
  if (source_leds.empty()) return {};
  const std::size_t need = sources_bytes(header, outputs, source_leds.size());
  const std::size_t may = memory_given(options);
  if (need <= may) return {};
  MapRotations map_rotations(options);
  size_t i = 0;
  map_rotations.for_each(
      [&](const relight::EnvironmentMap& map, double rotation, const std::string&) {
        outputs[i++].lighting =
            relight::split_lighting(map, header.lights(), rotation, coverage_rad(options), false);
      });
  source_leds.clear();
  char note[240];
  std::snprintf(note, sizeof note,
                "compact sources relit by the LED cells: rendering them at their direction would "
                "hold %.0f MiB for this %dx%d field, over the %.0f MiB it may use (--memory)",
                double(need) / (1 << 20), header.width(), header.height(), double(may) / (1 << 20));
  return note;
}

// Under MPI: each rank relights its bands of rows (round robin) into its outputs and keeps those
// rows in a spill beside the output folder; rank 0 reads the others' rows into its outputs (and
// goes on: true). The other ranks return false once their rows are there.
bool relight_split_over_ranks(const RelightOptions& options, capture::FieldStream& stream,
                              const Ranks& ranks,
                              const std::function<void(int y0, int y1)>& relight_rows,
                              std::vector<Output>& outputs) {
  const int width = stream.width(), height = stream.height();
  const int rows = band_rows_for_ranks(height, height, stream.row_alignment(), ranks.size());
  const fs::path dir = options.out_dir.string() + ".partial";
  if (ranks.root()) {
    std::error_code error;
    fs::remove_all(dir, error);
    fs::create_directories(dir, error);
    if (error) {
      throw InputError(dir.string() +
                       ": cannot create the folder the ranks gather their rows in (" +
                       error.message() + ")");
    }
  }
  ranks.barrier();  // The folder is there, empty.
  ScratchFile spill(dir / "relit.spill",
                    "the images relit under MPI are gathered through a file beside the output "
                    "folder: it needs their size free there",
                    ScratchFile::Lifetime::kKept);
  const std::size_t row_floats = std::size_t(width) * 3;
  const auto at = [&](std::size_t o, int y) { return (o * height + std::size_t(y)) * row_floats; };
  for (int b = ranks.rank(), y0; (y0 = b * rows) < height; b += ranks.size()) {
    const int y1 = std::min(height, y0 + rows);
    relight_rows(y0, y1);
    for (std::size_t o = 0; o < outputs.size(); ++o) {
      spill.write(&outputs[o].relit.pixels[std::size_t(y0) * row_floats],
                  std::size_t(y1 - y0) * row_floats, at(o, y0));
    }
  }
  spill.sync();
  ranks.barrier();  // Every rank's rows are in the spill.
  if (!ranks.root()) return false;
  spill.reopen();  // Its pages as the others wrote them (a file system shared between nodes).
  for (int b = 0, y0; (y0 = b * rows) < height; ++b) {
    if (b % ranks.size() == 0) continue;  // Rank 0's own.
    const int y1 = std::min(height, y0 + rows);
    for (std::size_t o = 0; o < outputs.size(); ++o) {
      spill.read(&outputs[o].relit.pixels[std::size_t(y0) * row_floats],
                 std::size_t(y1 - y0) * row_floats, at(o, y0));
    }
  }
  std::error_code ignored;
  fs::remove_all(dir, ignored);
  return true;
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
  const std::string sources_note = fit_sources_in_memory(options, header, outputs, source_leds);
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
  } else if (!relight_split_over_ranks(options, stream, ranks, relight_rows, outputs)) {
    return;  // Rank 0 writes the images.
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
        memory_given(options) - sources_bytes(header, outputs, source_leds.size());
    const relight::FieldSources sources(header, stream.bands(stream.rows_within(band_bytes)),
                                        {source_leds.begin(), source_leds.end()});
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
      char ms[96];
      std::snprintf(ms, sizeof ms, " (normals and shadows of the sources' LEDs: %.0f ms, all maps)",
                    sources_ms);
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

// Rows of maps a band within what full-size outputs (output_bytes) leave of the memory given: a
// row of maps is read as the file's channels, then copied into the maps.
int map_band_rows(const RelightOptions& options, const ExrLayout& layout,
                  std::size_t output_bytes) {
  const std::size_t row_bytes =
      std::size_t(layout.width) * layout.channel_names.size() * 2 * sizeof(float);
  const std::size_t may = memory_given(options);
  const std::size_t rows =
      (may > output_bytes ? may - output_bytes : 0) / std::max<std::size_t>(row_bytes, 1);
  return int(std::min<std::size_t>(std::size_t(layout.height), std::max<std::size_t>(16, rows)));
}

// `band`'s rows into `image` from row y0 on (same width and channels).
void paste_rows(const Image& band, Image& image, int y0) {
  std::copy(band.pixels.begin(), band.pixels.end(),
            image.pixels.begin() + std::ptrdiff_t(y0) * image.width * image.channels);
}

// Each edit's pixels changed, summed over the bands (`band`: one band's), and the report lines:
// "FILE: KIND[I] changed N pixels".
void add_counts(std::vector<int>& total, const std::vector<int>& band) {
  total.resize(band.size());
  for (size_t i = 0; i < band.size(); ++i) total[i] += band[i];
}
void report_edits(const fs::path& file, const char* kind, const std::vector<int>& counts,
                  RelightSummary& summary) {
  for (size_t i = 0; i < counts.size(); ++i) {
    summary.edit_reports.push_back(file.filename().string() + ": " + kind + "[" +
                                   std::to_string(i) + "] changed " + std::to_string(counts[i]) +
                                   " pixels");
  }
}

// Rows [y0, y1) of an image.
Image rows_of(const Image& image, int y0, int y1) {
  Image band(image.width, y1 - y0, image.channels);
  const std::size_t row = std::size_t(image.width) * image.channels;
  std::copy_n(image.pixels.begin() + std::ptrdiff_t(y0 * row), (y1 - y0) * row,
              band.pixels.begin());
  return band;
}

// One render of the models: its lighting, the field relit under it for the flagged pixels (when
// a field is given), the image and the time the render took.
struct ModelOutput {
  std::string name;
  relight::LightingForModels lighting;
  bool directional = false;                 // --light: no field fallback, no detail line.
  std::string lights_note;                  // How the lighting was made (and its time).
  std::vector<float> field_irradiance_rgb;  // The field's weights; empty: no fallback.
  Image fallback, relit;
  double render_ms = 0;
};

// The fitted maps (edited when asked) rendered under each map, read a band of rows at a time
// whatever their size (each band rendered under every lighting before the next is read) into
// full-size outputs; a field, when given too, is relit for the pixels the fit flagged in one pass
// over its file, and bounds the models' light to the dome's coverage.
void relight_models(const RelightOptions& options, RelightSummary& summary,
                    const ProgressFn& progress) {
  const ExrLayout layout = exr_layout(options.models_file);
  const int width = layout.width, height = layout.height;
  std::optional<relight::ModelEdits> edits;
  if (!options.edits_file.empty()) {
    edits = relight::read_model_edits(options.edits_file, width, height);
  }
  std::optional<capture::FieldStream> field;
  FieldLights lights;
  if (!options.field_file.empty()) {
    field.emplace(options.field_file);
    if (field->width() != width || field->height() != height) {
      throw InputError(options.field_file.string() + ": size: expected " + std::to_string(width) +
                       "x" + std::to_string(height) + " (the size of " +
                       options.models_file.string() + "), got " + std::to_string(field->width()) +
                       "x" + std::to_string(field->height()));
    }
    lights = field_lights(field->header());
  }
  // With a field, the models get the light the field gets (the dome's coverage): the fit saw no
  // other, and a lobe aimed below the dome is not bounded by any measurement.
  relight::EnvironmentSampling sampling;
  sampling.directions_width = options.directions_width;
  sampling.covered_by_leds = lights.dirs;
  sampling.coverage_radius_rad = coverage_rad(options);
  std::vector<ModelOutput> outputs;
  if (options.light_dir) {
    // The field cannot be lit from an arbitrary direction: flagged pixels stay black here.
    ModelOutput& out = outputs.emplace_back();
    out.name = "light";
    out.lighting =
        relight::LightingForModels::directional(*options.light_dir, Eigen::Vector3d::Ones());
    out.directional = true;
  }
  MapRotations map_rotations(options);
  map_rotations.for_each([&](const relight::EnvironmentMap& map, double rotation,
                             const std::string& name) {
    const auto t0 = Clock::now();
    ModelOutput& out = outputs.emplace_back();
    out.name = name;
    out.lighting = relight::LightingForModels::environment(map, rotation, sampling);
    if (field) {
      out.field_irradiance_rgb = relight::integrate_environment(map, lights.dirs, rotation,
                                                                coverage_rad(options), lights.valid)
                                     .irradiance_rgb;
      out.fallback = Image(width, height, 3);
    }
    char note[128];
    std::snprintf(note, sizeof note, "lights %.1f ms (%zu directions%s)",
                  ms_between(t0, Clock::now()), out.lighting.dirs_in_stage.size(),
                  field ? " within the dome; field for flagged pixels" : " over the sphere");
    out.lights_note = note;
  });
  if (field) {
    field->read_rows_planar(0, height, [&](const capture::PlanarRows& rows) {
      for (ModelOutput& out : outputs) {
        if (!out.field_irradiance_rgb.empty()) {
          relight::relight_rows_into(rows, out.field_irradiance_rgb, out.fallback);
        }
      }
    });
  }
  std::size_t output_bytes = 0;
  for (ModelOutput& out : outputs) {
    out.relit = Image(width, height, 3);
    output_bytes += (out.relit.pixels.size() + out.fallback.pixels.size()) * sizeof(float);
  }
  const int rows = map_band_rows(options, layout, output_bytes);
  std::vector<int> edit_counts;
  relight::ModelRenderOptions render;
  for (int y0 = 0; y0 < height; y0 += rows) {
    const int y1 = std::min(height, y0 + rows);
    relight::ModelMaps band = relight::read_model_map_rows(options.models_file, y0, y1);
    if (edits) {
      add_counts(edit_counts, relight::apply_model_edits(*edits, band, y0));
    }
    Image fallback;
    for (ModelOutput& out : outputs) {
      const auto t0 = Clock::now();
      render.flagged_fallback = nullptr;
      if (!out.fallback.pixels.empty()) {
        fallback = rows_of(out.fallback, y0, y1);
        render.flagged_fallback = &fallback;
      }
      paste_rows(relight::render_models(band, out.lighting, render), out.relit, y0);
      out.render_ms += ms_between(t0, Clock::now());
    }
    if (y1 < height) report(progress, "render models (rows)", y1, height);
  }
  report_edits(options.edits_file, "edits", edit_counts, summary);
  RelitWriter writer(options, summary);
  long done = 0;
  for (ModelOutput& out : outputs) {
    char detail[224];
    std::snprintf(detail, sizeof detail, "%s, model render %.1f ms", out.lights_note.c_str(),
                  out.render_ms);
    if (out.directional) {
      writer.write(out.name, out.relit);
    } else {
      writer.write(out.name, out.relit, detail, total_luma(out.lighting.irradiance_rgb));
    }
    report(progress, "relight", ++done, long(outputs.size()), out.name);
  }
}

// The time-varying models of `lightstage fit --time` at the scene time (time edits from the edits
// file: relight/time/temporal_render.h), rendered as the models are: the maps read a band of rows
// at a time (the edits' transfers summarised by passes over the bands first).
void relight_temporal(const RelightOptions& options, RelightSummary& summary,
                      const ProgressFn& progress) {
  const ExrLayout layout = exr_layout(options.temporal_file);
  const int width = layout.width, height = layout.height;
  const double time_s = *options.time_s;
  relight::EnvironmentSampling sampling;
  sampling.directions_width = options.directions_width;
  char suffix[32];
  std::snprintf(suffix, sizeof suffix, "_t%.0fs", time_s);
  std::vector<ModelOutput> outputs;
  if (options.light_dir) {
    ModelOutput& out = outputs.emplace_back();
    out.name = std::string("light") + suffix;
    out.lighting =
        relight::LightingForModels::directional(*options.light_dir, Eigen::Vector3d::Ones());
  }
  MapRotations map_rotations(options);
  map_rotations.for_each(
      [&](const relight::EnvironmentMap& map, double rotation, const std::string& name) {
        ModelOutput& out = outputs.emplace_back();
        out.name = name + suffix;
        out.lighting = relight::LightingForModels::environment(map, rotation, sampling);
      });
  std::size_t output_bytes = 0;
  for (ModelOutput& out : outputs) {
    out.relit = Image(width, height, 3);
    output_bytes += out.relit.pixels.size() * sizeof(float);
  }
  const int rows = map_band_rows(options, layout, output_bytes);
  const relight::TemporalMapsBands bands =
      [&](const std::function<void(relight::TemporalMaps&, int)>& visit) {
        for (int y0 = 0; y0 < height; y0 += rows) {
          relight::TemporalMaps band = relight::read_temporal_map_rows(options.temporal_file, y0,
                                                                       std::min(height, y0 + rows));
          visit(band, y0);
        }
      };
  std::optional<relight::TemporalEdits> edits;
  std::vector<std::optional<relight::TemporalTransfer>> transfers;
  if (!options.edits_file.empty()) {
    edits = relight::read_temporal_edits(options.edits_file, width, height);
    transfers = relight::temporal_transfers(*edits, bands);
  }
  std::vector<int> edit_counts;
  int extrapolated = 0;
  bands([&](relight::TemporalMaps& band, int y0) {
    summary.first_time_s = band.first_time_s();
    summary.last_time_s = band.last_time_s();
    if (edits) {
      add_counts(edit_counts, relight::apply_temporal_edits(*edits, transfers, band, y0));
    }
    for (size_t o = 0; o < outputs.size(); ++o) {
      int band_extrapolated = 0;
      const Image relit =
          relight::render_temporal(band, time_s, outputs[o].lighting, {}, &band_extrapolated);
      paste_rows(relit, outputs[o].relit, y0);
      if (o == 0) extrapolated += band_extrapolated;  // The same pixels under every lighting.
    }
    const int y1 = y0 + band.maps.height;
    if (y1 < height) report(progress, "render at t (rows)", y1, height);
  });
  report_edits(options.edits_file, "time", edit_counts, summary);
  RelitWriter writer(options, summary);
  long done = 0;
  for (ModelOutput& out : outputs) {
    writer.write(out.name, out.relit);
    report(progress, "relight at t", ++done, long(outputs.size()), out.name);
  }
  summary.extrapolated_pixels = extrapolated;
}

}  // namespace

RelightSummary relight(const RelightOptions& options, const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("relight: " + problem);
  }
  RelightSummary summary;
  std::string title;
  const Ranks& ranks = Ranks::world();
  if (ranks.size() > 1 && (!options.models_file.empty() || !options.temporal_file.empty())) {
    throw InputError(
        "relight: under MPI only a field is relit with its bands split over the "
        "ranks; run --models and --temporal as one process (without mpirun)");
  }
  if (!options.temporal_file.empty()) {
    relight_temporal(options, summary, progress);
    title = "temporal: " + options.temporal_file.filename().string();
  } else if (!options.models_file.empty()) {
    relight_models(options, summary, progress);
    title = "models: " + options.models_file.filename().string();
  } else {
    relight_field(options, summary, progress);
    if (!ranks.root()) return summary;  // Rank 0 writes the images.
    title = "relit: " + options.field_file.filename().string();
  }
  if (!options.edits_file.empty()) title += " + " + options.edits_file.filename().string();
  std::vector<Preview> previews;
  for (const RelitImage& image : summary.images) previews.push_back({image.png, image.label});
  summary.contact_sheet = options.out_dir / "contact_sheet.png";
  write_contact_sheet(summary.contact_sheet, previews, title);
  return summary;
}

}  // namespace ls::jobs
