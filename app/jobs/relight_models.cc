// lightstage relight --models and --temporal: fitted and time-varying models rendered a band of
// maps at a time.
#include <algorithm>
#include <cstdio>
#include <functional>
#include <optional>

#include "app/jobs/relight_outputs.h"
#include "capture/field_file.h"
#include "lightstage/bands.h"
#include "lightstage/errors.h"
#include "lightstage/exr_channels.h"
#include "relight/fit/model_edit.h"
#include "relight/fit/model_render.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "relight/sources/map_relight.h"
#include "relight/time/temporal_render.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

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

// The band height under MPI: at most a band per rank four times over (fit_bands.h), so that
// every rank renders some.
int split_rows(int rows, int height, const Ranks& ranks) {
  return ranks.size() > 1 ? std::min(rows, band_rows_for_ranks(height, height, 1, ranks.size()))
                          : rows;
}

// The bands of `rows` rows this process renders: every band, or under MPI its own (round robin).
template <class Fn>
void for_own_bands(const Ranks& ranks, int height, int rows, Fn&& render) {
  for (int b = ranks.rank(), y0; (y0 = b * rows) < height; b += ranks.size()) {
    render(y0, std::min(height, y0 + rows));
  }
}

// Under MPI the outputs' rows and the counts (each edit's pixels, then `extra`) gathered on rank
// 0 (gather_rows_over_ranks); true on rank 0 (and without MPI), false on the others.
template <class Outputs>
bool gathered(const RelightOptions& options, const Ranks& ranks, int rows, Outputs& outputs,
              std::vector<int>& edit_counts, int* extra = nullptr) {
  if (ranks.size() == 1) return true;
  std::vector<Image*> images;
  images.reserve(outputs.size());
  for (auto& out : outputs) images.push_back(&out.relit);
  std::vector<long> counts(edit_counts.begin(), edit_counts.end());
  if (extra) counts.push_back(*extra);
  if (!gather_rows_over_ranks(options, ranks, rows, images, counts)) return false;
  std::copy_n(counts.begin(), edit_counts.size(), edit_counts.begin());
  if (extra) *extra = int(counts.back());
  return true;
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
}  // namespace

void relight_models(const RelightOptions& options, RelightSummary& summary,
                    const ProgressFn& progress) {
  const ExrLayout layout = exr_layout(options.models_file);
  const int width = layout.width, height = layout.height;
  std::optional<relight::ModelEdits> edits;
  if (!options.edits_file.empty()) {
    edits = relight::read_model_edits(options.edits_file, width, height);
  }
  std::optional<capture::FieldStream> field;
  std::vector<capture::FieldLight> lights;
  if (!options.field_file.empty()) {
    field.emplace(options.field_file);
    if (field->width() != width || field->height() != height) {
      throw InputError(options.field_file.string() + ": size: expected " + std::to_string(width) +
                       "x" + std::to_string(height) + " (the size of " +
                       options.models_file.string() + "), got " + std::to_string(field->width()) +
                       "x" + std::to_string(field->height()));
    }
    lights = field->header().lights();
  }
  // With a field, the models get the light the field gets (the dome's coverage): the fit saw no
  // other, and a lobe aimed below the dome is not bounded by any measurement.
  relight::EnvironmentSampling sampling;
  sampling.directions_width = options.directions_width;
  sampling.covered_by_leds = capture::light_directions(lights);
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
  map_rotations.for_each(
      [&](const physics::EnvironmentMap& map, double rotation, const std::string& name) {
        const auto t0 = Clock::now();
        ModelOutput& out = outputs.emplace_back();
        out.name = name;
        out.lighting = relight::LightingForModels::environment(map, rotation, sampling);
        if (field) {  // The whole map by the LEDs' cells: the flagged pixels have no shape to cast.
          relight::MapRelightOptions cells;
          cells.coverage_rad = coverage_rad(options);
          cells.bright_sources = false;
          out.field_irradiance_rgb =
              relight::map_lighting(map, field->header().lights(), rotation, cells)
                  .weights.irradiance_rgb;
          out.fallback = Image(width, height, 3);
        }
        char note[128];
        std::snprintf(note, sizeof note, "lights %.1f ms (%zu directions%s)",
                      ms_between(t0, Clock::now()), out.lighting.dirs_in_stage.size(),
                      field ? " within the dome; field for flagged pixels" : " over the sphere");
        out.lights_note = note;
      });
  std::size_t output_bytes = 0;
  for (ModelOutput& out : outputs) {
    out.relit = Image(width, height, 3);
    output_bytes += (out.relit.pixels.size() + out.fallback.pixels.size()) * sizeof(float);
  }
  const Ranks& ranks = Ranks::world();
  const int rows = split_rows(map_band_rows(options, layout, output_bytes), height, ranks);
  if (field) {  // The field under every map for the flagged pixels of this process's bands.
    for_own_bands(ranks, height, ranks.size() > 1 ? rows : height, [&](int y0, int y1) {
      field->read_rows_planar(y0, y1, [&](const capture::PlanarRows& piece) {
        for (ModelOutput& out : outputs) {
          if (!out.field_irradiance_rgb.empty()) {
            relight::relight_rows_into(piece, out.field_irradiance_rgb, out.fallback);
          }
        }
      });
    });
  }
  std::vector<int> edit_counts(edits ? edits->edits.size() : 0, 0);
  relight::ModelRenderOptions render;
  for_own_bands(ranks, height, rows, [&](int y0, int y1) {
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
  });
  if (!gathered(options, ranks, rows, outputs, edit_counts)) return;  // Rank 0 writes.
  summary.ranks = ranks.size();
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
      [&](const physics::EnvironmentMap& map, double rotation, const std::string& name) {
        ModelOutput& out = outputs.emplace_back();
        out.name = name + suffix;
        out.lighting = relight::LightingForModels::environment(map, rotation, sampling);
      });
  std::size_t output_bytes = 0;
  for (ModelOutput& out : outputs) {
    out.relit = Image(width, height, 3);
    output_bytes += out.relit.pixels.size() * sizeof(float);
  }
  const Ranks& ranks = Ranks::world();
  const int rows = split_rows(map_band_rows(options, layout, output_bytes), height, ranks);
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
  std::vector<int> edit_counts(edits ? edits->edits.size() : 0, 0);
  int extrapolated = 0;
  for_own_bands(ranks, height, rows, [&](int y0, int y1) {
    relight::TemporalMaps band = relight::read_temporal_map_rows(options.temporal_file, y0, y1);
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
    if (y1 < height) report(progress, "render at t (rows)", y1, height);
  });
  if (!gathered(options, ranks, rows, outputs, edit_counts, &extrapolated)) return;
  summary.ranks = ranks.size();
  report_edits(options.edits_file, "time", edit_counts, summary);
  RelitWriter writer(options, summary);
  long done = 0;
  for (ModelOutput& out : outputs) {
    writer.write(out.name, out.relit);
    report(progress, "relight at t", ++done, long(outputs.size()), out.name);
  }
  summary.extrapolated_pixels = extrapolated;
}

}  // namespace ls::jobs
