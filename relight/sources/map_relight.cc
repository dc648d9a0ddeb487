#include "relight/sources/map_relight.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <string>
#include <utility>

#include "capture/field_file.h"
#include "capture/reduced_field.h"
#include "lightstage/errors.h"
#include "lightstage/progress.h"
#include "relight/lighting/relight.h"
#include "relight/sources/guided_upsample.h"

namespace ls::relight {

namespace {

double ms_since(Clock::time_point start) { return 1e3 * seconds_since(start); }

// The LEDs whose images the sources of `relit` need, and how many LED triangles they fall in.
std::set<int> source_leds(const std::vector<MapRelit>& relit, int* triangles = nullptr) {
  std::set<int> leds;
  for (const MapRelit& r : relit) {
    for (const int led : r.lighting.leds()) leds.insert(led);
    if (triangles == nullptr) continue;
    for (const PlacedSource& source : r.lighting.sources) *triangles += source.triangle.has_value();
  }
  return leds;
}

// What is left out for want of memory, one line: `what` would hold `need` bytes.
std::string over_memory(const char* what, std::size_t need, std::size_t may, int width,
                        int height) {
  char line[300];
  std::snprintf(line, sizeof line,
                "%s would hold %.0f MiB for this %dx%d field, over the %.0f MiB it may use", what,
                double(need) / (1 << 20), width, height, double(may) / (1 << 20));
  return line;
}

// Each source's irradiance given to the LEDs of its triangle by their weights, per LED (a
// LightWeights::irradiance_rgb): the field relit by them is the source as the LEDs show it.
std::vector<float> source_led_irradiance(const SplitLighting& lighting, int num_lights) {
  std::vector<float> irradiance(3 * std::size_t(num_lights), 0.0f);
  for (const PlacedSource& source : lighting.sources) {
    if (!source.triangle) continue;
    for (int k = 0; k < 3; ++k) {
      const auto led = std::size_t(source.triangle->leds[size_t(k)]);
      for (int c = 0; c < 3; ++c) {
        irradiance[3 * led + size_t(c)] +=
            float(source.triangle->weights[size_t(k)] * source.in_stage.irradiance_rgb[c]);
      }
    }
  }
  return irradiance;
}

// Unbounded, the bands a field is reduced in for its sources: large enough to read at the disk's
// rate, small beside the field.
constexpr std::size_t kReducedBandBytes = std::size_t(128) << 20;

void check_options(const MapRelightOptions& options) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("relighting under a map: " + problem);
  }
}

}  // namespace

std::string MapRelightOptions::validate() const {
  if (!std::isfinite(coverage_rad)) return "coverage: expected a finite angle";
  if (source_pixels != 0 && source_pixels < kFewestSourcePixels) {
    return "source pixels: expected 0 (the field's size) or at least " +
           std::to_string(kFewestSourcePixels) + " (64x64), not " + std::to_string(source_pixels);
  }
  return split.validate();
}

SplitLighting map_lighting(const physics::EnvironmentMap& map,
                           const std::vector<capture::FieldLight>& lights, double rotation_deg,
                           const MapRelightOptions& options) {
  return split_lighting(map, lights, rotation_deg, options.coverage_rad, options.bright_sources,
                        options.split);
}

MapRelighter::MapRelighter(std::vector<capture::FieldLight> lights, int width, int height,
                           MapRelightOptions options)
    : options_(options),
      lights_(std::move(lights)),
      width_(width),
      height_(height),
      geometry_(options_.source_geometry) {
  check_options(options_);
}

MapRelighter::MapRelighter(const capture::ReflectanceField& field, MapRelightOptions options)
    : MapRelighter(field.lights(), field.width(), field.height(), options) {
  field_ = &field;
}

MapRelighter::MapRelighter(const PcaField& pca, MapRelightOptions options)
    : MapRelighter(pca.lights(), pca.width(), pca.height(), options) {
  pca_ = &pca;
}

MapRelighter::MapRelighter(capture::FieldStream& stream, MapRelightOptions options)
    : MapRelighter(stream.header().lights(), stream.width(), stream.height(), options) {
  stream_ = &stream;
}

MapRelighter::~MapRelighter() = default;

SplitLighting MapRelighter::lighting(const physics::EnvironmentMap& map,
                                     double rotation_deg) const {
  return map_lighting(map, lights_, rotation_deg, options_);
}

bool MapRelighter::renders_sources(const SplitLighting& lighting) {
  return std::any_of(lighting.sources.begin(), lighting.sources.end(),
                     [](const PlacedSource& s) { return s.triangle.has_value(); });
}

FieldSources& MapRelighter::sources(const ProgressFn& progress) {
  if (sources_) return *sources_;
  LS_CHECK(stream_ == nullptr, "MapRelighter: a streamed field's sources are made in relight_all");
  if (field_ != nullptr) {
    sources_ = std::make_unique<FieldSources>(*field_);
  } else {
    const capture::ReflectanceField header = pca_->header();
    sources_ =
        std::make_unique<FieldSources>(header, pca_->reconstruction_bands(),
                                       [pca = pca_](int led) { return pca->led_image(led); });
  }
  if (geometry_) {
    sources_->recover_geometry(progress);
  }
  return *sources_;
}

void MapRelighter::prepare(const std::vector<SplitLighting>& lightings,
                           const ProgressFn& progress) {
  std::set<int> leds;
  for (const SplitLighting& lighting : lightings) {
    for (const int led : lighting.leds()) leds.insert(led);
  }
  sources(progress).prepare({leds.begin(), leds.end()});
}

void MapRelighter::render_cells(const SplitLighting& lighting, Image& out) const {
  LS_CHECK(stream_ == nullptr, "MapRelighter: a streamed field is relit by relight_all");
  if (field_ != nullptr) {
    relight_into(*field_, lighting.weights.irradiance_rgb, out);
  } else {
    pca_->relight_led_weights_into(lighting.weights.irradiance_rgb.data(), out);
  }
}

bool MapRelighter::add_sources(const SplitLighting& lighting, Image& out,
                               const std::vector<const Image*>& visibility,
                               FieldSources::ShapeUse use) {
  return !renders_sources(lighting) || sources().add(lighting, out, visibility, use);
}

void MapRelighter::recover_geometry(const ProgressFn& progress) {
  sources().recover_geometry(progress);
}

void MapRelighter::trace_shapes(const SplitLighting& lighting) {
  if (renders_sources(lighting)) sources().trace_shapes(lighting);
}

void MapRelighter::render(const SplitLighting& lighting, Image& out,
                          const std::vector<const Image*>& visibility) {
  render_cells(lighting, out);
  add_sources(lighting, out, visibility);
}

void MapRelighter::render_timed(MapRelit& r) {
  auto t0 = Clock::now();
  render_cells(r.lighting, r.image);
  r.relight_ms = ms_since(t0);
  t0 = Clock::now();
  add_sources(r.lighting, r.image);
  r.sources_ms = ms_since(t0);
  r.geometry = geometry_ && renders_sources(r.lighting);
}

MapRelit MapRelighter::relight(const physics::EnvironmentMap& map, double rotation_deg) {
  MapRelit out;
  const auto t0 = Clock::now();
  out.lighting = lighting(map, rotation_deg);
  out.weights_ms = ms_since(t0);
  render_timed(out);
  return out;
}

std::string MapRelighter::fit_in_memory(const std::vector<MapRotation>& maps,
                                        std::vector<MapRelit>& relit) {
  int triangles = 0;
  const std::set<int> leds = source_leds(relit, &triangles);
  const std::size_t may = options_.memory_bytes;
  if (leds.empty() || may == 0) return {};
  const auto need = [&](bool geometry) {
    return sources_bytes(int(leds.size()), triangles, int(maps.size()), geometry);
  };
  std::string note;
  if (geometry_) {
    if (need(true) <= may) return {};
    note = over_memory("bright sources' shadows by the LEDs' flows alone: the scene's shape",
                       need(true), may, width_, height_);
    geometry_ = false;
  }
  if (need(false) <= may) return note;
  MapRelightOptions cells = options_;
  cells.bright_sources = false;
  for (std::size_t i = 0; i < maps.size(); ++i) {
    relit[i].lighting = map_lighting(*maps[i].map, lights_, maps[i].rotation_deg, cells);
  }
  return over_memory("bright sources relit by the LED cells: rendering them at their direction",
                     need(false), may, width_, height_);
}

MapRelitSet MapRelighter::relight_all(const std::vector<MapRotation>& maps, const RowPass& pass,
                                      const ProgressFn& progress) {
  MapRelitSet out;
  if (stream_ != nullptr) {
    relight_streamed(maps, pass, progress, out);
    return out;
  }
  for (const MapRotation& m : maps) {
    const auto t0 = Clock::now();
    out.relit.emplace_back().lighting = lighting(*m.map, m.rotation_deg);
    out.relit.back().weights_ms = ms_since(t0);
  }
  const std::string note = fit_in_memory(maps, out.relit);
  for (MapRelit& r : out.relit) {
    render_timed(r);
    r.note = note;
  }
  return out;
}

// The field read once a few MiB at a time (FieldStream's rows as the file holds them) whatever
// its size: each piece relit under every map before the next is read, into full-size images.
// Then the sources, from a second pass in bands.
void MapRelighter::relight_streamed(const std::vector<MapRotation>& maps, const RowPass& pass,
                                    const ProgressFn& progress, MapRelitSet& out) {
  std::vector<MapRelit>& relit = out.relit;
  for (const MapRotation& m : maps) {
    const auto t0 = Clock::now();
    MapRelit& r = relit.emplace_back();
    r.lighting = lighting(*m.map, m.rotation_deg);
    r.weights_ms = ms_since(t0);
    r.image = Image(width_, height_, 3);
  }
  const std::string note = fit_in_memory(maps, relit);
  int triangles = 0;
  const std::set<int> leds = source_leds(relit, &triangles);
  // Relighting sums over each pixel's values: it needs no pixel-major band.
  const auto pass_start = Clock::now();
  const auto relight_rows = [&](int y0, int y1) {
    stream_->read_rows_planar(y0, y1, [&](const capture::PlanarRows& rows) {
      for (MapRelit& r : relit) {
        const auto t0 = Clock::now();
        relight_rows_into(rows, r.lighting.weights.irradiance_rgb, r.image);
        r.relight_ms += ms_since(t0);
      }
      const int done = rows.first_row + rows.rows;
      if (done < height_) report(progress, "relight (rows)", done, height_);
    });
  };
  if (pass.rows.empty()) relight_rows(0, height_);
  for (const auto& [y0, y1] : pass.rows) relight_rows(y0, y1);
  if (pass.gather) {
    std::vector<Image*> images;
    images.reserve(relit.size());
    for (MapRelit& r : relit) images.push_back(&r.image);
    if (!pass.gather(images)) {
      out.complete = false;
      return;
    }
  }
  out.rows_pass_s = ms_since(pass_start) / 1e3;
  double sources_ms = 0;
  if (!leds.empty() && source_factor() > 1) {
    const auto t0 = Clock::now();
    add_reduced_sources(relit, progress);
    sources_ms = ms_since(t0);
  } else if (!leds.empty()) {
    const auto t0 = Clock::now();
    report(progress, "bright sources (normals)", 0, 1);
    // Bands within what the sources' images leave of the memory given.
    const std::size_t need = FieldSources::bytes_needed(
        width_, height_, int(leds.size()), triangles, geometry_ ? int(lights_.size()) : 0);
    const int rows = options_.memory_bytes > 0 ? stream_->rows_within(options_.memory_bytes - need)
                                               : stream_->band_rows(MemoryBudget{});
    const FieldSources streamed(stream_->header(), stream_->bands(rows), {leds.begin(), leds.end()},
                                geometry_, progress);
    for (MapRelit& r : relit) streamed.add(r.lighting, r.image);
    sources_ms = ms_since(t0);
  }
  for (MapRelit& r : relit) {
    r.sources_ms = sources_ms;
    r.geometry = geometry_ && !leds.empty();
    r.note = note;
  }
}

int MapRelighter::source_factor() const {
  const double pixels = double(width_) * height_;
  if (stream_ == nullptr || options_.source_pixels == 0 || pixels <= double(options_.source_pixels))
    return 1;
  return int(std::ceil(std::sqrt(pixels / double(options_.source_pixels))));
}

std::size_t MapRelighter::sources_bytes(int leds, int triangles, int maps, bool geometry) const {
  const int factor = source_factor();
  const int width = (width_ + factor - 1) / factor, height = (height_ + factor - 1) / factor;
  std::size_t bytes = FieldSources::bytes_needed(width, height, leds, triangles,
                                                 geometry ? int(lights_.size()) : 0);
  if (factor > 1) {
    // Each map's guide at the field's size and reduced.
    bytes +=
        std::size_t(maps) *
        (std::size_t(width_) * std::size_t(height_) + std::size_t(width) * std::size_t(height)) *
        3 * sizeof(float);
  }
  return bytes;
}

void MapRelighter::add_reduced_sources(std::vector<MapRelit>& relit, const ProgressFn& progress) {
  const int factor = source_factor();
  const capture::ReflectanceField header = capture::reduced_header(stream_->header(), factor);
  // Per map: the source's irradiance on the LEDs around it, and the field relit by them at full
  // size and reduced (the guides).
  std::vector<std::vector<float>> led_irradiance;
  std::vector<Image> guides, guides_reduced;
  for (const MapRelit& r : relit) {
    led_irradiance.push_back(source_led_irradiance(r.lighting, int(lights_.size())));
    guides.emplace_back(width_, height_, 3);
    guides_reduced.emplace_back(header.width(), header.height(), 3);
  }
  int triangles = 0;
  const std::set<int> leds = source_leds(relit, &triangles);
  const std::size_t need = sources_bytes(int(leds.size()), triangles, int(relit.size()), geometry_);
  const std::size_t band_bytes = options_.memory_bytes > need
                                     ? std::min(kReducedBandBytes, options_.memory_bytes - need)
                                     : kReducedBandBytes;
  char phase[96];
  std::snprintf(phase, sizeof phase, "bright sources (the field at %dx%d)", header.width(),
                header.height());
  ProgressFn reduced_progress;
  if (progress) {
    reduced_progress = [&](const std::string&, long done, long total, const std::string& detail) {
      progress(phase, done, total, detail);
    };
  }
  const capture::FieldBands reduced = capture::reduced_bands(
      *stream_, factor, band_bytes, reduced_progress, [&](const capture::PlanarRows& rows) {
        for (std::size_t i = 0; i < relit.size(); ++i) {
          relight_rows_into(rows, led_irradiance[i], guides[i]);
        }
      });
  const FieldSources sources(
      header,
      [&](const capture::BandVisitor& visit) {
        Image band_relit;
        reduced([&](const capture::ReflectanceField& band) {
          for (std::size_t i = 0; i < relit.size(); ++i) {
            relight_into(band, led_irradiance[i], band_relit);
            std::copy(band_relit.pixels.begin(), band_relit.pixels.end(),
                      guides_reduced[i].pixels.begin() +
                          3 * std::ptrdiff_t(band.first_row()) * band.width());
          }
          visit(band);
        });
      },
      {leds.begin(), leds.end()}, geometry_, progress);
  for (std::size_t i = 0; i < relit.size(); ++i) {
    Image low(header.width(), header.height(), 3);
    sources.add(relit[i].lighting, low);
    add_guided_upsample(low, guides_reduced[i], guides[i], factor, relit[i].image);
    guides[i] = Image();
  }
}

}  // namespace ls::relight
